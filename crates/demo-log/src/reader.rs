//! Demos back to flat arrays for the trainer.

use crate::DemoError;
use crate::schemas::STEP_SCHEMA_NAME;
use crate::writer::TOPIC_STEP;
use mcap::records::Record;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One episode's steps as flat row-major arrays.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Episode {
    /// Observations, `T × obs_dim`, row-major.
    pub obs: Vec<f32>,
    /// Actions, `T × act_dim`, row-major.
    pub actions: Vec<f32>,
    /// Rewards, `T`.
    pub rewards: Vec<f32>,
    /// Terminated flags, `T`.
    pub terminated: Vec<bool>,
    /// Truncated flags, `T`.
    pub truncated: Vec<bool>,
    /// Step times, seconds, `T`.
    pub t: Vec<f64>,
    /// Observation length.
    pub obs_dim: usize,
    /// Action length.
    pub act_dim: usize,
    /// The `episode` metadata record (or `episode_start` for a file that was never finished).
    pub meta: BTreeMap<String, String>,
}

impl Episode {
    /// Number of steps.
    pub fn len(&self) -> usize {
        self.rewards.len()
    }

    /// Whether there are no steps.
    pub fn is_empty(&self) -> bool {
        self.rewards.is_empty()
    }
}

#[derive(Deserialize)]
struct StepIn {
    step: u64,
    t: f64,
    obs: Vec<f32>,
    action: Vec<f32>,
    reward: f64,
    terminated: bool,
    truncated: bool,
}

fn fmt_err(path: &Path, reason: impl Into<String>) -> DemoError {
    DemoError::Format { path: path.to_path_buf(), reason: reason.into() }
}

/// Read the steps of one demo from its bytes (`name` is used in errors).
///
/// # Errors
/// [`DemoError::Format`] for a file that is not a complete MCAP demo, has no `/demo/step` channel
/// with schema [`STEP_SCHEMA_NAME`], has a step that does not parse, or steps that are not 0, 1, 2,
/// ... with constant obs/action lengths. A cut or damaged file is refused: use
/// [`crate::salvage_to`] first. A salvaged file may skip the step ranges its `salvage` metadata
/// record declares lost (`step_gaps`); the row before each gap is marked truncated, and the
/// salvage record's entries are in `meta` as `salvage.<key>`.
pub fn read_demo_bytes(buf: &[u8], name: &Path) -> Result<Episode, DemoError> {
    let mut st = ReadState {
        name,
        ep: Episode::default(),
        step_channels: Vec::new(),
        step_schemas: Vec::new(),
        start_meta: None,
        end_meta: None,
        salvage_meta: None,
        saw_footer: false,
        messages: 0,
        next_step: 0,
        jumps: Vec::new(),
    };
    const MAGIC: &[u8] = crate::scan::MAGIC;
    match crate::scan::file_start(buf) {
        _ if buf.len() < 2 * MAGIC.len() => return Err(fmt_err(name, "not an MCAP file (bad magic)")),
        crate::scan::Start::Magic => {}
        crate::scan::Start::DamagedMagic => {
            return Err(fmt_err(
                name,
                format!(
                    "damaged MCAP ({}); `salvage_to` recovers its complete messages",
                    crate::scan::damaged_magic_text(buf)
                ),
            ));
        }
        crate::scan::Start::NotMcap => return Err(fmt_err(name, "not an MCAP file (bad magic)")),
    }
    let damaged = |e: String| {
        fmt_err(
            name,
            format!("damaged or incomplete MCAP ({e}); `salvage_to` recovers its complete messages"),
        )
    };
    let mut pos = MAGIC.len();
    loop {
        if buf.len() - pos < 9 {
            return Err(damaged(format!("cut at byte {pos}, before the footer")));
        }
        let op = buf[pos];
        let len = u64::from_le_bytes(buf[pos + 1..pos + 9].try_into().expect("8 bytes"));
        let start = pos + 9;
        if len > (buf.len() - start) as u64 {
            return Err(damaged(format!("record at byte {pos} runs past the end of the file")));
        }
        let end = start + len as usize;
        let body = &buf[start..end];
        pos = end;
        match op {
            mcap::records::op::CHUNK => {
                let Record::Chunk { header, data } = crate::scan::parse_checked(op, body).map_err(damaged)?
                else {
                    return Err(damaged("chunk record does not parse".into()));
                };
                let decoded = crate::scan::decode_chunk(&header, &data).map_err(damaged)?;
                let mut err: Option<DemoError> = None;
                crate::scan::for_each_record(&decoded, |op, body| {
                    // Messages of other channels are skipped without being parsed or copied.
                    if op == mcap::records::op::MESSAGE {
                        let (ch, data) =
                            crate::scan::message_parts(body).ok_or("message record too short")?;
                        st.messages += 1;
                        if st.step_channels.contains(&ch) {
                            return st.step(data).map_err(|e| {
                                let m = e.to_string();
                                err = Some(e);
                                m
                            });
                        }
                        return Ok(());
                    }
                    if !crate::scan::is_parsed_kind(op) {
                        return Ok(());
                    }
                    let r = crate::scan::parse_checked(op, body)?;
                    st.record(r).map_err(|e| {
                        let m = e.to_string();
                        err = Some(e);
                        m
                    })
                })
                .map_err(|e| err.take().unwrap_or_else(|| damaged(e)))?;
            }
            mcap::records::op::MESSAGE => {
                let (ch, data) = crate::scan::message_parts(body)
                    .ok_or_else(|| damaged("message record too short".into()))?;
                st.messages += 1;
                if st.step_channels.contains(&ch) {
                    st.step(data)?;
                }
            }
            mcap::records::op::DATA_END if body.len() == 4 => {
                // The CRC of every byte before this record: metadata records, message indexes
                // and chunk headers have no CRC of their own (a flipped bit in `control_dt` shows
                // only here).
                let crc = u32::from_le_bytes(body.try_into().expect("4 bytes"));
                let record_start = start - 9;
                if crc != 0 && crc32fast::hash(&buf[..record_start]) != crc {
                    return Err(damaged(
                        "data section CRC mismatch: bytes outside the chunks' own CRCs (metadata, \
                         message indexes, chunk headers) are damaged"
                            .into(),
                    ));
                }
            }
            mcap::records::op::FOOTER => {
                crate::scan::parse_checked(op, body).map_err(damaged)?;
                if &buf[pos..] != MAGIC {
                    return Err(damaged("no end magic after the footer".into()));
                }
                st.saw_footer = true;
                break;
            }
            k if crate::scan::is_parsed_kind(k) => {
                let r = crate::scan::parse_checked(op, body).map_err(damaged)?;
                st.record(r)?;
            }
            _ => {}
        }
    }
    if !st.saw_footer {
        return Err(fmt_err(
            name,
            "incomplete MCAP (no footer); `salvage_to` recovers its complete messages",
        ));
    }
    let (summary_problem, summary_count) = crate::scan::summary_check(buf);
    if let Some(p) = summary_problem {
        return Err(damaged(format!("summary not usable: {p}")));
    }
    if let Some(n) = summary_count
        && n != st.messages
    {
        return Err(damaged(format!("summary counts {n} messages, the chunks hold {}", st.messages)));
    }
    if st.step_channels.is_empty() {
        return Err(fmt_err(name, format!("no {TOPIC_STEP} channel: not a mimicrete demo")));
    }
    st.check_gaps()?;
    let mut ep = st.ep;
    ep.meta = st.end_meta.or(st.start_meta).unwrap_or_default();
    for (k, v) in st.salvage_meta.unwrap_or_default() {
        ep.meta.insert(format!("salvage.{k}"), v);
    }
    Ok(ep)
}

struct ReadState<'p> {
    name: &'p Path,
    ep: Episode,
    step_channels: Vec<u16>,
    step_schemas: Vec<u16>,
    start_meta: Option<BTreeMap<String, String>>,
    end_meta: Option<BTreeMap<String, String>>,
    /// The last `salvage` metadata record (written by [`crate::salvage_to`]).
    salvage_meta: Option<BTreeMap<String, String>>,
    saw_footer: bool,
    /// Message records seen (all channels), to compare with the summary's statistics.
    messages: u64,
    next_step: u64,
    /// Steps skipped: `(row, expected step, step found)`.
    jumps: Vec<(usize, u64, u64)>,
}

impl ReadState<'_> {
    fn record(&mut self, rec: Record<'_>) -> Result<(), DemoError> {
        match rec {
            Record::Schema { header, .. } if header.name == STEP_SCHEMA_NAME => {
                self.step_schemas.push(header.id);
            }
            Record::Channel(c) if c.topic == TOPIC_STEP => {
                if !self.step_schemas.contains(&c.schema_id) {
                    return Err(fmt_err(
                        self.name,
                        format!(
                            "channel {TOPIC_STEP} does not use schema {STEP_SCHEMA_NAME} (unknown version?)"
                        ),
                    ));
                }
                if !self.step_channels.contains(&c.id) {
                    self.step_channels.push(c.id);
                }
            }
            Record::Metadata(m) if crate::meta::CHECKED_RECORDS.contains(&m.name.as_str()) => {
                crate::meta::check_episode_record(&m.metadata).map_err(|e| {
                    fmt_err(self.name, format!("metadata record \"{}\": {e}; the file is damaged", m.name))
                })?;
                match m.name.as_str() {
                    "episode" => self.end_meta = Some(m.metadata),
                    _ => self.start_meta = Some(m.metadata),
                }
            }
            Record::Metadata(m) if m.name == "salvage" => self.salvage_meta = Some(m.metadata),
            Record::Footer(_) => self.saw_footer = true,
            _ => {}
        }
        Ok(())
    }

    /// Steps may be missing only where the `salvage` record's `step_gaps` says they were lost;
    /// the row before each gap is then marked truncated (the rows around a gap are not
    /// consecutive).
    fn check_gaps(&mut self) -> Result<(), DemoError> {
        let Some(&(_, want, got)) = self.jumps.first() else { return Ok(()) };
        let undeclared = || fmt_err(self.name, format!("step {got} found where step {want} was expected"));
        let declared = self
            .salvage_meta
            .as_ref()
            .and_then(|m| m.get("step_gaps"))
            .and_then(|g| crate::salvage::parse_gaps(g))
            .ok_or_else(undeclared)?;
        for &(row, a, b) in &self.jumps {
            if !declared.contains(&(a, b)) {
                return Err(fmt_err(
                    self.name,
                    format!(
                        "step {b} found where step {a} was expected, and the salvage record does not declare steps {a}..{b} lost"
                    ),
                ));
            }
            if row > 0 {
                self.ep.truncated[row - 1] = true;
            }
        }
        Ok(())
    }

    fn step(&mut self, data: &[u8]) -> Result<(), DemoError> {
        let ep = &mut self.ep;
        let name = self.name;
        let s: StepIn = serde_json::from_slice(data)
            .map_err(|e| fmt_err(name, format!("step message {} does not parse: {e}", ep.len())))?;
        if s.step < self.next_step {
            return Err(fmt_err(
                name,
                format!("step {} found where step {} was expected", s.step, self.next_step),
            ));
        }
        if s.step > self.next_step {
            // Allowed only where a `salvage` record declares the steps lost (checked at the end).
            self.jumps.push((ep.len(), self.next_step, s.step));
        }
        self.next_step = s.step.saturating_add(1);
        if ep.is_empty() {
            ep.obs_dim = s.obs.len();
            ep.act_dim = s.action.len();
        } else if s.obs.len() != ep.obs_dim || s.action.len() != ep.act_dim {
            return Err(fmt_err(
                name,
                format!(
                    "step {}: obs/action lengths {}/{} differ from {}/{}",
                    s.step,
                    s.obs.len(),
                    s.action.len(),
                    ep.obs_dim,
                    ep.act_dim
                ),
            ));
        }
        ep.obs.extend_from_slice(&s.obs);
        ep.actions.extend_from_slice(&s.action);
        ep.rewards.push(s.reward as f32);
        ep.terminated.push(s.terminated);
        ep.truncated.push(s.truncated);
        ep.t.push(s.t);
        Ok(())
    }
}

/// Read one demo file.
///
/// # Errors
/// [`DemoError::Io`] if it cannot be read, else as [`read_demo_bytes`].
pub fn read_demo(path: impl AsRef<Path>) -> Result<Episode, DemoError> {
    let path = path.as_ref();
    let buf = crate::read_input(path)?;
    read_demo_bytes(&buf, path)
}

/// The `*.mcap` entries of a directory, sorted by name (`*.mcap.partial` files are not listed).
/// Every entry with the name is listed, whatever it is: a dangling symbolic link or a named pipe
/// called `x.mcap` is then refused by name when it is read ([`crate::read_input`]) instead of
/// being left out without a word.
///
/// # Errors
/// [`DemoError::Io`] if the directory cannot be listed.
pub fn demo_files(dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, DemoError> {
    let dir = dir.as_ref();
    let rd = std::fs::read_dir(dir).map_err(|e| DemoError::Io { path: dir.to_path_buf(), source: e })?;
    let mut out = Vec::new();
    for entry in rd {
        let entry = entry.map_err(|e| DemoError::Io { path: dir.to_path_buf(), source: e })?;
        let p = entry.path();
        if p.extension().is_some_and(|x| x == "mcap") {
            out.push(p);
        }
    }
    out.sort();
    Ok(out)
}

/// Many episodes concatenated, as the trainer wants them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Dataset {
    /// `N × obs_dim`, row-major.
    pub obs: Vec<f32>,
    /// `N × act_dim`, row-major.
    pub actions: Vec<f32>,
    /// `N`.
    pub rewards: Vec<f32>,
    /// `N`.
    pub terminated: Vec<bool>,
    /// `N`.
    pub truncated: Vec<bool>,
    /// Episode index of each row: the position of its file in `files` (`N`).
    pub episode: Vec<u32>,
    /// Observation length.
    pub obs_dim: usize,
    /// Action length.
    pub act_dim: usize,
    /// The files read, in order.
    pub files: Vec<PathBuf>,
    /// Each file's metadata record.
    pub metas: Vec<BTreeMap<String, String>>,
}

/// Read and concatenate demos: a single file, or every `*.mcap` in a directory (sorted by name).
/// Files are read on up to `available_parallelism` threads.
///
/// # Errors
/// The first file's error (by file order); [`DemoError::Format`] if obs/action lengths differ
/// between files or a directory holds no demo.
pub fn load_dataset(path: impl AsRef<Path>) -> Result<Dataset, DemoError> {
    let path = path.as_ref();
    let files = if path.is_dir() {
        let f = demo_files(path)?;
        if f.is_empty() {
            return Err(fmt_err(path, "no *.mcap demos in this directory"));
        }
        f
    } else {
        vec![path.to_path_buf()]
    };
    let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1).min(files.len()).max(1);
    let mut results: Vec<Option<Result<Episode, DemoError>>> = (0..files.len()).map(|_| None).collect();
    std::thread::scope(|s| {
        let chunks: Vec<_> = results.chunks_mut(files.len().div_ceil(threads)).collect();
        let per = files.len().div_ceil(threads);
        for (k, slot) in chunks.into_iter().enumerate() {
            let files = &files;
            s.spawn(move || {
                for (j, r) in slot.iter_mut().enumerate() {
                    *r = Some(read_demo(&files[k * per + j]));
                }
            });
        }
    });
    let mut ds = Dataset::default();
    for (i, r) in results.into_iter().enumerate() {
        let ep = r.expect("every slot is filled by its thread")?;
        if i == 0 || ds.rewards.is_empty() {
            ds.obs_dim = ep.obs_dim;
            ds.act_dim = ep.act_dim;
        } else if !ep.is_empty() && (ep.obs_dim, ep.act_dim) != (ds.obs_dim, ds.act_dim) {
            return Err(fmt_err(
                &files[i],
                format!(
                    "obs/action lengths {}/{} differ from the earlier files' {}/{}",
                    ep.obs_dim, ep.act_dim, ds.obs_dim, ds.act_dim
                ),
            ));
        }
        ds.obs.extend_from_slice(&ep.obs);
        ds.actions.extend_from_slice(&ep.actions);
        ds.rewards.extend_from_slice(&ep.rewards);
        ds.terminated.extend_from_slice(&ep.terminated);
        ds.truncated.extend_from_slice(&ep.truncated);
        ds.episode.extend(std::iter::repeat_n(i as u32, ep.len()));
        ds.metas.push(ep.meta);
    }
    ds.files = files;
    Ok(ds)
}
