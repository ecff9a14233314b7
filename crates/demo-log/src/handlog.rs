//! Hand logs: JSON Lines, a header line then one frame per line (see the crate docs for the format).
//!
//! Parsing is all-or-nothing in [`ParseMode::Strict`] (the first bad line aborts with
//! `file:line: reason`) and skip-and-report in [`ParseMode::Lenient`] (bad and untracked frames are
//! dropped, the [`ParseReport`] says which lines and why). A bad header aborts in both modes.

use serde_json::{Map, Value};
use std::fmt;
use std::path::Path;
use ur3_kin::{HandLayout, Handedness, Space};

/// The `format` field every hand-log header carries.
pub const HANDLOG_FORMAT: &str = "mimicrete.handlog";
/// The hand-log format version this crate reads and writes.
pub const HANDLOG_VERSION: u64 = 1;

const HEADER_KEYS: [&str; 10] = [
    "format",
    "version",
    "layout",
    "space",
    "handedness",
    "units",
    "task",
    "episode_seed",
    "source",
    "extra",
];
const FRAME_KEYS: [&str; 4] = ["t", "tracked", "joints", "orientations"];

/// The largest joint coordinate accepted, metres. A tracked hand is metres from its tracking
/// origin; a value beyond 10 km is a unit or encoding error, and near `f64::MAX` it would
/// overflow to infinity in the first distance computed downstream.
pub const MAX_COORD_M: f64 = 1e4;

fn coordinate_in_range(x: f64, what: &dyn Fn() -> String) -> Result<f64, String> {
    if x.abs() > MAX_COORD_M {
        let shown = if x.abs() < 1e6 { format!("{x}") } else { format!("{x:e}") };
        return Err(format!(
            "{} is {shown} m, out of range (at most {MAX_COORD_M} m from the origin; hand logs are in metres)",
            what()
        ));
    }
    Ok(x)
}

/// A malformed hand log: where (file, 1-based line) and why. Displays as `file:line: reason`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HandLogError {
    /// The file name (or the source name given to [`HandLog::parse_str`]).
    pub file: String,
    /// 1-based line number.
    pub line: usize,
    /// What is wrong, in words.
    pub reason: String,
}

impl fmt::Display for HandLogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}: {}", self.file, self.line, self.reason)
    }
}

impl std::error::Error for HandLogError {}

/// How to treat bad frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ParseMode {
    /// The first bad line aborts the parse; untracked frames are kept.
    #[default]
    Strict,
    /// Bad frames and untracked frames are skipped and reported; only a bad header aborts.
    Lenient,
}

impl ParseMode {
    /// `"strict"` or `"lenient"`.
    pub fn from_name(name: &str) -> Option<ParseMode> {
        match name.to_ascii_lowercase().as_str() {
            "strict" => Some(ParseMode::Strict),
            "lenient" => Some(ParseMode::Lenient),
            _ => None,
        }
    }

    /// [`ParseMode::from_name`], or [`crate::DemoError::Invalid`] naming the two modes.
    ///
    /// # Errors
    /// Any other name.
    pub fn parse(name: &str) -> Result<ParseMode, crate::DemoError> {
        ParseMode::from_name(name).ok_or_else(|| {
            crate::DemoError::Invalid(format!("mode must be 'strict' or 'lenient', got {name:?}"))
        })
    }
}

/// A line the lenient parser dropped.
/// Serialized as the pair `(line, reason)`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[serde(into = "(usize, String)")]
pub struct SkippedLine {
    /// 1-based line number.
    pub line: usize,
    /// Why it was dropped (the same text strict mode would have reported; `"untracked frame"`
    /// for a valid frame with `tracked: false`).
    pub reason: String,
}

impl From<SkippedLine> for (usize, String) {
    fn from(s: SkippedLine) -> (usize, String) {
        (s.line, s.reason)
    }
}

/// What a parse saw.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize)]
pub struct ParseReport {
    /// Frame lines seen (non-blank lines after the header).
    pub frame_lines: usize,
    /// Frames kept.
    pub kept: usize,
    /// Valid frames dropped because `tracked` was false (lenient mode only).
    pub untracked_skipped: usize,
    /// Invalid lines dropped (lenient mode only).
    pub invalid_skipped: usize,
    /// Every dropped line with its reason, in file order.
    pub skipped: Vec<SkippedLine>,
    /// SHA-256 (lower-case hex) of exactly the bytes parsed, when they were read from a file by
    /// [`HandLog::from_path`] (a log that grows while it is converted is hashed as it was read).
    pub sha256: Option<String>,
}

/// The header line of a hand log.
#[derive(Debug, Clone, PartialEq)]
pub struct HandLogHeader {
    /// Joint order.
    pub layout: HandLayout,
    /// Coordinate space of the positions (`"webxr"` parses to [`Space::OpenXr`]: same axes).
    pub space: Space,
    /// Which hand.
    pub handedness: Handedness,
    /// The task the demonstrator performed (`"suction"`, ...), if recorded.
    pub task: Option<String>,
    /// The simulator seed the demonstrator saw, if any.
    pub episode_seed: Option<u64>,
    /// Where the log came from (device, program), free text.
    pub source: Option<String>,
    /// Anything else, as a JSON object.
    pub extra: Option<Map<String, Value>>,
}

impl HandLogHeader {
    /// A header with only the required fields.
    pub fn new(layout: HandLayout, space: Space, handedness: Handedness) -> Self {
        HandLogHeader { layout, space, handedness, task: None, episode_seed: None, source: None, extra: None }
    }

    /// The header as the JSON object written on line 1.
    pub fn to_json(&self) -> Value {
        let mut m = Map::new();
        m.insert("format".into(), Value::from(HANDLOG_FORMAT));
        m.insert("version".into(), Value::from(HANDLOG_VERSION));
        m.insert("layout".into(), Value::from(self.layout.name()));
        m.insert("space".into(), Value::from(self.space.name()));
        m.insert("handedness".into(), Value::from(self.handedness.name()));
        m.insert("units".into(), Value::from("m"));
        if let Some(t) = &self.task {
            m.insert("task".into(), Value::from(t.as_str()));
        }
        if let Some(s) = self.episode_seed {
            m.insert("episode_seed".into(), Value::from(s));
        }
        if let Some(s) = &self.source {
            m.insert("source".into(), Value::from(s.as_str()));
        }
        if let Some(e) = &self.extra {
            m.insert("extra".into(), Value::Object(e.clone()));
        }
        Value::Object(m)
    }
}

/// One tracked-hand sample.
#[derive(Debug, Clone, PartialEq)]
pub struct HandFrame {
    /// Seconds since the log's start (any origin), non-decreasing along the log.
    pub t: f64,
    /// Whether the runtime tracked the hand in this frame.
    pub tracked: bool,
    /// Joint positions, metres, in the header's space and layout order.
    pub joints: Vec<[f64; 3]>,
    /// Joint orientations as quaternions `[x, y, z, w]`, if the runtime gives them.
    pub orientations: Option<Vec<[f64; 4]>>,
}

/// A parsed hand log.
#[derive(Debug, Clone, PartialEq)]
pub struct HandLog {
    /// Line 1.
    pub header: HandLogHeader,
    /// The frames kept, in file order.
    pub frames: Vec<HandFrame>,
}

fn err(file: &str, line: usize, reason: impl Into<String>) -> HandLogError {
    HandLogError { file: file.to_string(), line, reason: reason.into() }
}

/// Replace the bare tokens `NaN`, `Infinity` and `-Infinity` (which Python's `json` writes but JSON
/// forbids) outside strings by the strings `"NaN"`, ... so that the frame checker can name them.
/// Returns `None` when the line has none (the common case: no copy).
fn quote_nonfinite_tokens(line: &str) -> Option<String> {
    if !(line.contains("NaN") || line.contains("Infinity")) {
        return None;
    }
    let b = line.as_bytes();
    let mut out = String::with_capacity(line.len() + 8);
    let mut in_str = false;
    let mut esc = false;
    let mut i = 0;
    let mut last = 0;
    while i < b.len() {
        let c = b[i];
        if in_str {
            if esc {
                esc = false;
            } else if c == b'\\' {
                esc = true;
            } else if c == b'"' {
                in_str = false;
            }
            i += 1;
            continue;
        }
        if c == b'"' {
            in_str = true;
            i += 1;
            continue;
        }
        // Compare bytes: `i` may sit inside a multi-byte character (found by the fuzzer).
        let rest = &b[i..];
        let tok = ["-Infinity", "Infinity", "NaN"].into_iter().find(|t| rest.starts_with(t.as_bytes()));
        if let Some(t) = tok {
            out.push_str(&line[last..i]);
            out.push('"');
            out.push_str(t);
            out.push('"');
            i += t.len();
            last = i;
        } else {
            i += 1;
        }
    }
    out.push_str(&line[last..]);
    Some(out)
}

/// A JSON value whose objects never hold a key twice. serde_json keeps the last of two equal
/// keys, so `{"handedness":"right", ..., "handedness":"left"}` would silently be a left hand;
/// deserializing through this type refuses it instead (at any depth).
struct UniqueKeys(Value);

const DUPLICATE_KEY: &str = "duplicate key";

impl<'de> serde::Deserialize<'de> for UniqueKeys {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(UniqueKeysVisitor).map(UniqueKeys)
    }
}

struct UniqueKeysVisitor;

impl<'de> serde::de::Visitor<'de> for UniqueKeysVisitor {
    type Value = Value;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, b: bool) -> Result<Value, E> {
        Ok(Value::Bool(b))
    }
    fn visit_i64<E>(self, n: i64) -> Result<Value, E> {
        Ok(Value::from(n))
    }
    fn visit_u64<E>(self, n: u64) -> Result<Value, E> {
        Ok(Value::from(n))
    }
    fn visit_f64<E>(self, x: f64) -> Result<Value, E> {
        Ok(serde_json::Number::from_f64(x).map_or(Value::Null, Value::Number))
    }
    fn visit_str<E>(self, s: &str) -> Result<Value, E> {
        Ok(Value::String(s.to_owned()))
    }
    fn visit_string<E>(self, s: String) -> Result<Value, E> {
        Ok(Value::String(s))
    }
    fn visit_unit<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_none<E>(self) -> Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Value, A::Error> {
        let mut v = Vec::with_capacity(seq.size_hint().unwrap_or(0).min(64));
        while let Some(UniqueKeys(x)) = seq.next_element()? {
            v.push(x);
        }
        Ok(Value::Array(v))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<Value, A::Error> {
        let mut m = Map::new();
        while let Some(k) = map.next_key::<String>()? {
            if m.contains_key(&k) {
                return Err(serde::de::Error::custom(format!("{DUPLICATE_KEY} \"{k}\"")));
            }
            let UniqueKeys(x) = map.next_value()?;
            m.insert(k, x);
        }
        Ok(Value::Object(m))
    }
}

fn parse_json_line(line: &str) -> Result<Value, String> {
    let quoted = quote_nonfinite_tokens(line);
    let text = quoted.as_deref().unwrap_or(line);
    serde_json::from_str::<UniqueKeys>(text).map(|u| u.0).map_err(|e| {
        let msg = e.to_string();
        if msg.contains("number out of range") {
            "non-finite value: a number overflows to infinity".to_string()
        } else if let Some(rest) = msg.strip_prefix(DUPLICATE_KEY) {
            // "duplicate key \"t\" at line 1 column 40": JSON allows it, but which value counts
            // is up to the reader; a hand log must say one thing.
            let key = rest.split(" at line ").next().unwrap_or(rest).trim();
            format!("{DUPLICATE_KEY} {key} (column {}): each field may appear once", e.column())
        } else {
            format!("invalid JSON: {msg}")
        }
    })
}

fn type_name(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a bool",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

/// A finite number or a reason naming `what`.
fn finite(v: &Value, what: &dyn Fn() -> String) -> Result<f64, String> {
    match v {
        Value::Number(n) => match n.as_f64() {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(format!("non-finite value in {}", what())),
        },
        Value::String(s) if matches!(s.as_str(), "NaN" | "Infinity" | "-Infinity") => {
            Err(format!("non-finite value ({s}) in {}", what()))
        }
        other => Err(format!("{} must be a number, got {}", what(), type_name(other))),
    }
}

fn parse_header(file: &str, text: Option<&str>) -> Result<HandLogHeader, HandLogError> {
    let e = |r: String| err(file, 1, r);
    let Some(line) = text else {
        return Err(e("missing header: the file is empty".into()));
    };
    let v = parse_json_line(line).map_err(|r| {
        if r.starts_with(DUPLICATE_KEY) {
            e(format!("header: {r}"))
        } else {
            e(format!("missing header: line 1 is not a JSON object ({r})"))
        }
    })?;
    let Value::Object(m) = v else {
        return Err(e(format!("missing header: line 1 is {}, not a JSON object", type_name(&v))));
    };
    let Some(format) = m.get("format") else {
        return Err(e(format!(
            "missing header: line 1 has no \"format\" field (expected \"format\":\"{HANDLOG_FORMAT}\")"
        )));
    };
    if format.as_str() != Some(HANDLOG_FORMAT) {
        return Err(e(format!("unknown format {format} in header (expected \"{HANDLOG_FORMAT}\")")));
    }
    match m.get("version") {
        None => return Err(e("header: missing field \"version\"".into())),
        Some(v) if v.as_u64() == Some(HANDLOG_VERSION) => {}
        Some(v) => {
            return Err(e(format!(
                "header: unsupported version {v} (this reader knows version {HANDLOG_VERSION})"
            )));
        }
    }
    for k in m.keys() {
        if !HEADER_KEYS.contains(&k.as_str()) {
            return Err(e(format!(
                "header: unknown field \"{k}\" (known: {}; put custom data under \"extra\")",
                HEADER_KEYS.join(", ")
            )));
        }
    }
    let req_str = |k: &str| -> Result<&str, HandLogError> {
        match m.get(k) {
            None => Err(e(format!("header: missing field \"{k}\""))),
            Some(Value::String(s)) => Ok(s.as_str()),
            Some(v) => Err(e(format!("header: \"{k}\" must be a string, got {}", type_name(v)))),
        }
    };
    let layout_name = req_str("layout")?;
    let layout = HandLayout::from_name(layout_name).map_err(|_| {
        e(format!(
            "header: unknown layout \"{layout_name}\" (known: {})",
            HandLayout::ALL.map(|l| l.name()).join(", ")
        ))
    })?;
    let space_name = req_str("space")?;
    let space = Space::from_name(space_name).map_err(|_| {
        e(format!("header: unknown space \"{space_name}\" (known: openxr, webxr, unity, robot_base)"))
    })?;
    let hand_name = req_str("handedness")?;
    let handedness = Handedness::from_name(hand_name)
        .map_err(|_| e(format!("header: unknown handedness \"{hand_name}\" (known: left, right)")))?;
    let units = req_str("units")?;
    if units != "m" {
        return Err(e(format!("header: unknown units \"{units}\" (hand logs are in metres: \"m\")")));
    }
    let opt_str = |k: &str| -> Result<Option<String>, HandLogError> {
        match m.get(k) {
            None | Some(Value::Null) => Ok(None),
            Some(Value::String(s)) => Ok(Some(s.clone())),
            Some(v) => Err(e(format!("header: \"{k}\" must be a string, got {}", type_name(v)))),
        }
    };
    let task = opt_str("task")?;
    let source = opt_str("source")?;
    let episode_seed =
        match m.get("episode_seed") {
            None | Some(Value::Null) => None,
            Some(v) => Some(v.as_u64().ok_or_else(|| {
                e(format!("header: \"episode_seed\" must be a non-negative integer, got {v}"))
            })?),
        };
    let extra = match m.get("extra") {
        None | Some(Value::Null) => None,
        Some(Value::Object(o)) => Some(o.clone()),
        Some(v) => return Err(e(format!("header: \"extra\" must be an object, got {}", type_name(v)))),
    };
    Ok(HandLogHeader { layout, space, handedness, task, episode_seed, source, extra })
}

/// Check one frame line; `prev_t` is the time of the last kept frame.
fn parse_frame(line: &str, layout: HandLayout, prev_t: Option<f64>) -> Result<HandFrame, String> {
    let v = parse_json_line(line)?;
    let Value::Object(m) = v else {
        return Err(format!("a frame must be a JSON object, got {}", type_name(&v)));
    };
    for k in m.keys() {
        if !FRAME_KEYS.contains(&k.as_str()) {
            return Err(format!("unknown frame field \"{k}\" (known: {})", FRAME_KEYS.join(", ")));
        }
    }
    let t = finite(m.get("t").ok_or("frame has no \"t\"")?, &|| "\"t\"".to_string())?;
    if let Some(p) = prev_t
        && t < p
    {
        return Err(format!("time goes backwards: t={t} after t={p}"));
    }
    let tracked = match m.get("tracked") {
        Some(Value::Bool(b)) => *b,
        None => return Err("frame has no \"tracked\"".into()),
        Some(v) => return Err(format!("\"tracked\" must be a bool, got {}", type_name(v))),
    };
    let n = layout.joint_count();
    let joints = match m.get("joints") {
        Some(Value::Array(a)) => a,
        None => return Err("frame has no \"joints\"".into()),
        Some(v) => return Err(format!("\"joints\" must be an array, got {}", type_name(v))),
    };
    if joints.len() != n {
        return Err(format!("wrong joint count: {} joints, layout {} has {n}", joints.len(), layout.name()));
    }
    let mut out = Vec::with_capacity(n);
    for (j, p) in joints.iter().enumerate() {
        let Value::Array(xyz) = p else {
            return Err(format!("joint {j} must be [x, y, z], got {}", type_name(p)));
        };
        if xyz.len() != 3 {
            return Err(format!("joint {j} must be [x, y, z], got {} numbers", xyz.len()));
        }
        let mut q = [0.0; 3];
        for (c, val) in xyz.iter().enumerate() {
            let what = || format!("joint {j} coordinate {}", ["x", "y", "z"][c]);
            q[c] = coordinate_in_range(finite(val, &what)?, &what)?;
        }
        out.push(q);
    }
    let orientations = match m.get("orientations") {
        None | Some(Value::Null) => None,
        Some(Value::Array(a)) => {
            if a.len() != n {
                return Err(format!(
                    "wrong orientation count: {} orientations, layout {} has {n} joints",
                    a.len(),
                    layout.name()
                ));
            }
            let mut o = Vec::with_capacity(n);
            for (j, p) in a.iter().enumerate() {
                let Value::Array(q4) = p else {
                    return Err(format!("orientation {j} must be [x, y, z, w], got {}", type_name(p)));
                };
                if q4.len() != 4 {
                    return Err(format!("orientation {j} must be [x, y, z, w], got {} numbers", q4.len()));
                }
                let mut q = [0.0; 4];
                for (c, val) in q4.iter().enumerate() {
                    q[c] = finite(val, &|| format!("orientation {j} component {}", ["x", "y", "z", "w"][c]))?;
                }
                o.push(q);
            }
            Some(o)
        }
        Some(v) => return Err(format!("\"orientations\" must be an array, got {}", type_name(v))),
    };
    Ok(HandFrame { t, tracked, joints: out, orientations })
}

impl HandLog {
    /// Parse hand-log text. `source_name` is the file name used in errors. A UTF-8 byte-order
    /// mark (BOM, U+FEFF) at the very start is accepted and skipped (Windows editors write one;
    /// RFC 8259 lets JSON readers ignore it); one at the start of a later line (files
    /// concatenated) is a bad line that says so.
    ///
    /// # Errors
    /// [`HandLogError`] (`file:line: reason`) for a bad header (both modes) or, in strict mode,
    /// the first bad frame line.
    pub fn parse_str(
        text: &str,
        source_name: &str,
        mode: ParseMode,
    ) -> Result<(HandLog, ParseReport), HandLogError> {
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        let ends_with_newline = text.ends_with('\n');
        let mut lines = text.lines().enumerate().peekable();
        // The header is the first non-blank line; it must be line 1.
        let first = lines.next().map(|(_, l)| l);
        let first = match first {
            Some(l) if l.trim().is_empty() => {
                return Err(err(source_name, 1, "missing header: line 1 is blank"));
            }
            other => other,
        };
        let header = parse_header(source_name, first)?;
        let layout = header.layout;
        let mut frames = Vec::new();
        let mut report = ParseReport::default();
        let mut prev_t: Option<f64> = None;
        while let Some((i, line)) = lines.next() {
            let lineno = i + 1;
            if line.trim().is_empty() {
                continue;
            }
            report.frame_lines += 1;
            let is_last = lines.peek().is_none();
            let parsed = if line.starts_with('\u{feff}') {
                Err("line starts with a UTF-8 byte-order mark (BOM), as where two files were \
                     concatenated; remove it"
                    .to_string())
            } else {
                parse_frame(line, layout, prev_t)
            };
            match parsed {
                Ok(f) => {
                    if !f.tracked && mode == ParseMode::Lenient {
                        report.untracked_skipped += 1;
                        report.skipped.push(SkippedLine { line: lineno, reason: "untracked frame".into() });
                        continue;
                    }
                    prev_t = Some(f.t);
                    frames.push(f);
                }
                Err(reason) => {
                    let reason = if is_last && !ends_with_newline && reason.starts_with("invalid JSON") {
                        format!("truncated last line (no newline at end of file and {reason})")
                    } else {
                        reason
                    };
                    match mode {
                        ParseMode::Strict => return Err(err(source_name, lineno, reason)),
                        ParseMode::Lenient => {
                            report.invalid_skipped += 1;
                            report.skipped.push(SkippedLine { line: lineno, reason });
                        }
                    }
                }
            }
        }
        report.kept = frames.len();
        Ok((HandLog { header, frames }, report))
    }

    /// Parse a hand-log file; errors name the path as given.
    ///
    /// # Errors
    /// [`HandLogError`]; an unreadable file, something that is not a regular file (a named pipe
    /// would block: see [`crate::read_input`]) or non-UTF-8 text is reported at line 1 / the line
    /// of the first bad byte.
    pub fn from_path(
        path: impl AsRef<Path>,
        mode: ParseMode,
    ) -> Result<(HandLog, ParseReport), HandLogError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let bytes = crate::files::read_regular(path).map_err(|e| match e {
            crate::files::ReadFail::NotRegular(reason) => err(&name, 1, reason),
            crate::files::ReadFail::Io(e) => err(&name, 1, format!("cannot read: {e}")),
        })?;
        let text = match std::str::from_utf8(&bytes) {
            Ok(t) => t,
            Err(u) => {
                let line = 1 + bytes[..u.valid_up_to()].iter().filter(|&&b| b == b'\n').count();
                if bytes.starts_with(&[0xff, 0xfe]) || bytes.starts_with(&[0xfe, 0xff]) {
                    return Err(err(
                        &name,
                        1,
                        "not UTF-8 text: the file starts with a UTF-16 byte-order mark (BOM); save it as UTF-8",
                    ));
                }
                return Err(err(&name, line, "not UTF-8 text"));
            }
        };
        let (log, mut report) = HandLog::parse_str(text, &name, mode)?;
        report.sha256 = Some(crate::sha256_hex(&bytes));
        Ok((log, report))
    }

    /// The log with every joint position converted into the robot Base frame through a ur3-kin
    /// [`Calibration`](ur3_kin::Calibration) (header space becomes `robot_base`). Orientations are
    /// dropped (a Unity log's are left-handed; nothing downstream uses them).
    ///
    /// # Errors
    /// [`HandLogError`] at line 1 when the calibration is for another space than the log's.
    pub fn to_robot_base(&self, cal: &ur3_kin::Calibration, name: &str) -> Result<HandLog, HandLogError> {
        if cal.space != self.header.space {
            return Err(err(
                name,
                1,
                format!(
                    "calibration is for space {} but the log is in space {}",
                    cal.space.name(),
                    self.header.space.name()
                ),
            ));
        }
        let frames = self
            .frames
            .iter()
            .map(|f| HandFrame {
                t: f.t,
                tracked: f.tracked,
                joints: f
                    .joints
                    .iter()
                    .map(|p| {
                        let b = cal.point_to_base(&ur3_kin::nalgebra::Vector3::new(p[0], p[1], p[2]));
                        [b.x, b.y, b.z]
                    })
                    .collect(),
                orientations: None,
            })
            .collect();
        let mut header = self.header.clone();
        header.space = Space::RobotBase;
        Ok(HandLog { header, frames })
    }

    /// Check the log as the strict parser would (joint counts, finite values, time order).
    ///
    /// # Errors
    /// [`HandLogError`] naming the line the offending frame would be written on.
    pub fn validate(&self, name: &str) -> Result<(), HandLogError> {
        let n = self.header.layout.joint_count();
        let mut prev: Option<f64> = None;
        for (i, f) in self.frames.iter().enumerate() {
            let line = i + 2;
            let bad = |r: String| Err(err(name, line, r));
            if !f.t.is_finite() {
                return bad("non-finite value in \"t\"".into());
            }
            if let Some(p) = prev
                && f.t < p
            {
                return bad(format!("time goes backwards: t={} after t={p}", f.t));
            }
            prev = Some(f.t);
            if f.joints.len() != n {
                return bad(format!(
                    "wrong joint count: {} joints, layout {} has {n}",
                    f.joints.len(),
                    self.header.layout.name()
                ));
            }
            if let Some(j) = f.joints.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
                return bad(format!("non-finite value in joint {j}"));
            }
            for (j, p) in f.joints.iter().enumerate() {
                for (c, &x) in p.iter().enumerate() {
                    coordinate_in_range(x, &|| format!("joint {j} coordinate {}", ["x", "y", "z"][c]))
                        .map_err(|r| err(name, line, r))?;
                }
            }
            if let Some(o) = &f.orientations {
                if o.len() != n {
                    return bad(format!(
                        "wrong orientation count: {} orientations, layout has {n} joints",
                        o.len()
                    ));
                }
                if let Some(j) = o.iter().position(|q| q.iter().any(|x| !x.is_finite())) {
                    return bad(format!("non-finite value in orientation {j}"));
                }
            }
        }
        Ok(())
    }

    /// The log as JSON Lines text (header, then one frame per line, each line ending in `\n`).
    /// Floats are written in their shortest round-tripping form, so parsing the text gives back
    /// exactly these numbers.
    ///
    /// # Errors
    /// [`HandLogError`] (file `"<memory>"`) when [`HandLog::validate`] fails.
    pub fn to_jsonl(&self) -> Result<String, HandLogError> {
        self.validate("<memory>")?;
        let mut s = String::with_capacity(64 + self.frames.len() * self.header.layout.joint_count() * 60);
        s.push_str(&self.header.to_json().to_string());
        s.push('\n');
        for f in &self.frames {
            s.push_str(&frame_json(f).to_string());
            s.push('\n');
        }
        Ok(s)
    }

    /// Write the log atomically (a temporary file renamed into place: never half-written).
    ///
    /// # Errors
    /// [`HandLogError`] for invalid content or an I/O failure (reported at line 1).
    pub fn write_jsonl(&self, path: impl AsRef<Path>) -> Result<(), HandLogError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        self.validate(&name)?;
        let text = self.to_jsonl().map_err(|e| HandLogError { file: name.clone(), ..e })?;
        let tmp = crate::partial_path(path);
        std::fs::write(&tmp, text).map_err(|e| err(&name, 1, format!("cannot write: {e}")))?;
        std::fs::rename(&tmp, path).map_err(|e| err(&name, 1, format!("cannot rename into place: {e}")))
    }
}

/// One frame as the JSON object written on its line.
pub fn frame_json(f: &HandFrame) -> Value {
    let mut m = Map::new();
    m.insert("t".into(), Value::from(f.t));
    m.insert("tracked".into(), Value::from(f.tracked));
    m.insert("joints".into(), Value::Array(f.joints.iter().map(|p| Value::from(p.to_vec())).collect()));
    if let Some(o) = &f.orientations {
        m.insert("orientations".into(), Value::Array(o.iter().map(|q| Value::from(q.to_vec())).collect()));
    }
    Value::Object(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nonfinite_tokens_are_quoted_outside_strings_only() {
        assert_eq!(quote_nonfinite_tokens("[1, NaN, -Infinity]").unwrap(), r#"[1, "NaN", "-Infinity"]"#);
        assert_eq!(quote_nonfinite_tokens(r#"{"a":"NaN"}"#).unwrap(), r#"{"a":"NaN"}"#);
        assert!(quote_nonfinite_tokens("[1,2]").is_none());
        // Multi-byte characters next to a token (a fuzzer find: slicing inside a character).
        assert_eq!(quote_nonfinite_tokens("é NaN ü").unwrap(), "é \"NaN\" ü");
        assert_eq!(quote_nonfinite_tokens("\u{10348}Infinity").unwrap(), "\u{10348}\"Infinity\"");
    }
}
