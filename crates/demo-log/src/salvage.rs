//! Recovery of damaged demos (crash, full disk, killed process, flipped bits) and verification.
//!
//! [`crate::scan::map_file`] walks the file record by record; after an unreadable record it
//! resynchronises on the next intact chunk (a Chunk record whose lengths add up and whose
//! decompressed records match its CRC), so every intact chunk is found wherever the damage is. A
//! chunk that is cut or damaged is lost whole. Schemas and channels come from every intact chunk,
//! the top-level records and an intact summary; when none of these has them (chunk 0 lost in a cut
//! file) and the file says it was written by demo-log, the writer's fixed channel layout is used.
//! [`salvage_to`] writes what was recovered as a complete file whose `salvage` metadata record
//! declares the lost step ranges (`step_gaps`), so that [`crate::read_demo`] accepts it.

use crate::DemoError;
use crate::scan::{FileMap, Start};
use crate::schemas;
use crate::writer::{DEMO_FORMAT, TOPIC_EVENTS, TOPIC_HAND, TOPIC_SCENE, TOPIC_STEP, TOPIC_TF};
use mcap::records::Record;
use serde::Serialize;
use serde::ser::{SerializeMap, Serializer};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A message recovered from a damaged file (serialized with `data` as bytes).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct RecoveredMessage {
    /// Channel topic (`/demo/step`, ...).
    pub topic: String,
    /// Schema name (empty if the channel has none).
    pub schema_name: String,
    /// Message encoding (`json`).
    pub message_encoding: String,
    /// Log time, ns.
    pub log_time: u64,
    /// Publish time, ns.
    pub publish_time: u64,
    /// Per-channel sequence number.
    pub sequence: u32,
    /// The message bytes.
    #[serde(serialize_with = "as_bytes")]
    pub data: Vec<u8>,
}

fn as_bytes<S: Serializer>(v: &[u8], s: S) -> Result<S::Ok, S::Error> {
    s.serialize_bytes(v)
}

/// `log_times` serialized as two fields, `log_time_start` and `log_time_end` (each null when
/// unknown).
fn log_time_fields<S: Serializer>(t: &Option<(u64, u64)>, s: S) -> Result<S::Ok, S::Error> {
    let mut m = s.serialize_map(Some(2))?;
    m.serialize_entry("log_time_start", &t.map(|t| t.0))?;
    m.serialize_entry("log_time_end", &t.map(|t| t.1))?;
    m.end()
}

/// One chunk as [`verify`] (and salvage) found it (serialized with `log_times` as the two fields
/// `log_time_start`, `log_time_end`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ChunkCheck {
    /// Position among the chunks of the file (0-based, file order).
    pub index: u64,
    /// Byte offset of the chunk record.
    pub offset: u64,
    /// Record length in bytes, when known.
    pub length: Option<u64>,
    /// Messages in the chunk (counted when intact, else from its message index records).
    pub messages: Option<u64>,
    /// First and last log time (ns) of its messages, when known.
    #[serde(flatten, serialize_with = "log_time_fields")]
    pub log_times: Option<(u64, u64)>,
    /// What is wrong with it (`None`: intact).
    pub error: Option<String>,
    /// Its messages can be recovered (intact, or only the header's log-time fields, which the CRC
    /// does not cover, are wrong).
    pub recoverable: bool,
}

/// What salvage found.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
pub struct SalvageReport {
    /// Size of the input, bytes.
    pub bytes_total: u64,
    /// Offset just past the last record that was read whole.
    pub bytes_used: u64,
    /// Intact chunks whose messages were recovered.
    pub chunks_ok: u64,
    /// Chunks lost (cut at the end, or damaged).
    pub chunks_lost: u64,
    /// The lost chunks.
    pub lost_chunks: Vec<ChunkCheck>,
    /// Messages recovered.
    pub messages: u64,
    /// Messages of intact chunks that could not be attributed to a channel (dropped).
    pub messages_unattributed: u64,
    /// Metadata records recovered.
    pub metadata: u64,
    /// Metadata records left out because a value readers rely on is damaged (metadata has no
    /// CRC of its own): `"name: reason"`, e.g. `episode: terminated is "urue", not true or false`.
    /// Without its `episode` record the salvaged demo reads as unfinished.
    pub metadata_dropped: Vec<String>,
    /// Attachments recovered.
    pub attachments: u64,
    /// Half-open ranges `[a, b)` of `/demo/step` step numbers that are missing between (or
    /// before) the recovered steps, and after them up to the episode's recorded `length`.
    pub step_gaps: Vec<(u64, u64)>,
    /// The channel layout was taken from the demo-log writer's fixed layout (the file's own
    /// Schema/Channel records were lost).
    pub layout_assumed: bool,
    /// The input was already a complete MCAP file (footer and end magic present).
    pub complete: bool,
    /// Why reading stopped early or skipped bytes, if it did (the first such reason).
    pub stopped_because: Option<String>,
    /// The leading magic was damaged (a few bits; the rest of the file was read as MCAP).
    pub magic_damaged: bool,
}

#[derive(Clone)]
struct SchemaInfo {
    name: String,
    encoding: String,
    data: Vec<u8>,
}

#[derive(Clone)]
struct ChannelInfo {
    topic: String,
    schema_id: u16,
    message_encoding: String,
    metadata: BTreeMap<String, String>,
}

/// Everything recoverable from a damaged file, in file order.
pub struct Salvaged {
    /// Complete messages.
    pub messages: Vec<RecoveredMessage>,
    /// Metadata records `(name, map)`.
    pub metadata: Vec<(String, BTreeMap<String, String>)>,
    /// Attachments.
    pub attachments: Vec<mcap::Attachment<'static>>,
    /// The report.
    pub report: SalvageReport,
    schemas: BTreeMap<u16, SchemaInfo>,
    channels: BTreeMap<u16, ChannelInfo>,
    channel_order: Vec<u16>,
}

/// The chunks of a file map as [`ChunkCheck`]s, in file order.
fn chunk_checks(m: &FileMap) -> Vec<ChunkCheck> {
    m.chunks
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let error = match (&c.content, c.header_times_wrong) {
                (Err(e), _) => Some(e.clone()),
                (Ok(_), true) => Some(
                    "the chunk header's log-time fields disagree with its messages (the messages are intact)"
                        .into(),
                ),
                (Ok(_), false) => None,
            };
            ChunkCheck {
                index: i as u64,
                offset: c.offset as u64,
                length: c.end.map(|e| (e - c.offset) as u64),
                messages: c.messages,
                log_times: c.log_times,
                error,
                recoverable: c.content.is_ok(),
            }
        })
        .collect()
}

fn add_schema_or_channel(
    r: &Record<'_>,
    schemas: &mut BTreeMap<u16, SchemaInfo>,
    channels: &mut BTreeMap<u16, ChannelInfo>,
    order: &mut Vec<u16>,
) {
    match r {
        Record::Schema { header, data } => {
            schemas.entry(header.id).or_insert_with(|| SchemaInfo {
                name: header.name.clone(),
                encoding: header.encoding.clone(),
                data: data.to_vec(),
            });
        }
        Record::Channel(c) => {
            if let std::collections::btree_map::Entry::Vacant(v) = channels.entry(c.id) {
                order.push(c.id);
                v.insert(ChannelInfo {
                    topic: c.topic.clone(),
                    schema_id: c.schema_id,
                    message_encoding: c.message_encoding.clone(),
                    metadata: c.metadata.clone(),
                });
            }
        }
        _ => {}
    }
}

/// Whether the file says it was written by this crate's [`crate::DemoWriter`]: its Header's
/// library, a metadata record with `format = mimicrete.demo`, or messages of an unknown channel 1
/// that are demo steps (JSON objects with `step`, `obs` and `action`).
fn written_by_demo_log(m: &FileMap) -> Option<BTreeMap<String, String>> {
    written_by_demo_log_records(m).or_else(|| {
        #[derive(serde::Deserialize)]
        #[allow(dead_code)]
        struct StepShape {
            step: u64,
            obs: Vec<f64>,
            action: Vec<f64>,
        }
        let mut ch1 = m.chunks.iter().flat_map(|c| c.content.iter().flatten()).filter_map(|r| match r {
            Record::Message { header, data } if header.channel_id == 1 => Some(data),
            _ => None,
        });
        let first = ch1.next()?;
        let is_step = |d: &[u8]| serde_json::from_slice::<StepShape>(d).is_ok();
        (is_step(first) && ch1.all(|d| is_step(d))).then(BTreeMap::new)
    })
}

fn written_by_demo_log_records(m: &FileMap) -> Option<BTreeMap<String, String>> {
    let mut by_header = false;
    let mut meta = None;
    for (_, r) in &m.records {
        match r {
            Record::Header(h) => by_header |= h.library.starts_with("mimicrete-demo-log/"),
            Record::Metadata(md) if md.metadata.get("format").map(String::as_str) == Some(DEMO_FORMAT) => {
                meta.get_or_insert_with(|| md.metadata.clone());
            }
            _ => {}
        }
    }
    if meta.is_some() { meta } else { by_header.then(BTreeMap::new) }
}

/// The schemas and channels [`crate::DemoWriter`] writes, with their ids (schemas and channels
/// 1..=5: step, hand, tf, scene, events). The hand channel's metadata comes from the episode
/// metadata. A test checks this against a written file.
fn demo_log_layout(meta: &BTreeMap<String, String>) -> Vec<(u16, SchemaInfo, ChannelInfo)> {
    let js = |name: &str, text: String| SchemaInfo {
        name: name.into(),
        encoding: "jsonschema".into(),
        data: text.into_bytes(),
    };
    let mut hand_md = BTreeMap::new();
    if let (Some(l), Some(s), Some(h)) =
        (meta.get("hand_layout"), meta.get("hand_space"), meta.get("handedness"))
    {
        if let Ok(layout) = ur3_kin::HandLayout::from_name(l) {
            hand_md.insert("layout".to_string(), l.clone());
            hand_md.insert("space".to_string(), s.clone());
            hand_md.insert("handedness".to_string(), h.clone());
            hand_md.insert("joint_count".to_string(), layout.joint_count().to_string());
            hand_md.insert("units".to_string(), "m".to_string());
        }
    }
    let rows = [
        (TOPIC_STEP, js(schemas::STEP_SCHEMA_NAME, schemas::step_schema()), BTreeMap::new()),
        (TOPIC_HAND, js(schemas::HAND_SCHEMA_NAME, schemas::hand_schema()), hand_md),
        (TOPIC_TF, js(schemas::TF_SCHEMA_NAME, schemas::tf_schema()), BTreeMap::new()),
        (TOPIC_SCENE, js(schemas::SCENE_SCHEMA_NAME, schemas::scene_schema()), BTreeMap::new()),
        (TOPIC_EVENTS, js(schemas::EVENT_SCHEMA_NAME, schemas::event_schema()), BTreeMap::new()),
    ];
    rows.into_iter()
        .enumerate()
        .map(|(i, (topic, schema, md))| {
            let id = i as u16 + 1;
            (
                id,
                schema,
                ChannelInfo {
                    topic: topic.into(),
                    schema_id: id,
                    message_encoding: "json".into(),
                    metadata: md,
                },
            )
        })
        .collect()
}

/// Step number of a `/demo/step` message.
fn step_number(data: &[u8]) -> Option<u64> {
    #[derive(serde::Deserialize)]
    struct S {
        step: u64,
    }
    serde_json::from_slice::<S>(data).ok().map(|s| s.step)
}

/// Missing step ranges given the recovered step numbers (increasing) and the recorded length.
fn gaps_of(steps: &[u64], length: Option<u64>) -> Vec<(u64, u64)> {
    let mut gaps = Vec::new();
    let mut next = 0u64;
    for &s in steps {
        if s > next {
            gaps.push((next, s));
        }
        next = next.max(s.saturating_add(1));
    }
    if let Some(l) = length.filter(|&l| l > next) {
        gaps.push((next, l));
    }
    gaps
}

/// `a..b,c..d` (empty for none).
pub(crate) fn format_gaps(g: &[(u64, u64)]) -> String {
    g.iter().map(|(a, b)| format!("{a}..{b}")).collect::<Vec<_>>().join(",")
}

/// Parse [`format_gaps`] output.
pub(crate) fn parse_gaps(s: &str) -> Option<Vec<(u64, u64)>> {
    if s.is_empty() {
        return Some(Vec::new());
    }
    s.split(',')
        .map(|r| {
            let (a, b) = r.split_once("..")?;
            let (a, b) = (a.trim().parse().ok()?, b.trim().parse().ok()?);
            (a < b).then_some((a, b))
        })
        .collect()
}

/// Recover everything intact from the bytes of a (possibly cut or damaged) MCAP file.
///
/// # Errors
/// [`DemoError::Format`] when the bytes do not start as MCAP (a
/// leading magic with a bit or two flipped is read on and reported as `magic_damaged`).
pub fn salvage_bytes(buf: &[u8], name: &Path) -> Result<Salvaged, DemoError> {
    let start = mcap_start(buf, name)?;
    let m = crate::scan::map_file(buf);
    let mut schemas = BTreeMap::new();
    let mut channels = BTreeMap::new();
    let mut order = Vec::new();
    for c in &m.chunks {
        for r in c.content.iter().flatten() {
            add_schema_or_channel(r, &mut schemas, &mut channels, &mut order);
        }
    }
    for (_, r) in &m.records {
        add_schema_or_channel(r, &mut schemas, &mut channels, &mut order);
    }
    if let Some(s) = &m.summary {
        for r in &s.records {
            add_schema_or_channel(r, &mut schemas, &mut channels, &mut order);
        }
    }
    let mut report = SalvageReport {
        bytes_total: buf.len() as u64,
        magic_damaged: start == Start::DamagedMagic,
        ..Default::default()
    };
    // A demo whose chunk 0 (schemas, channels) is lost and that has no intact summary: its
    // channels are the writer's fixed layout.
    let needs_layout = !channels.values().any(|c: &ChannelInfo| c.topic == TOPIC_STEP)
        || m.chunks.iter().any(|c| {
            c.content.iter().flatten().any(
                |r| matches!(r, Record::Message { header, .. } if !channels.contains_key(&header.channel_id)),
            )
        });
    if needs_layout {
        if let Some(meta) = written_by_demo_log(&m) {
            for (id, sc, ch) in demo_log_layout(&meta) {
                if !schemas.contains_key(&id) && !channels.contains_key(&id) {
                    schemas.insert(id, sc);
                    order.push(id);
                    channels.insert(id, ch);
                    report.layout_assumed = true;
                }
            }
            order.sort_unstable();
        }
    }
    let mut out = Salvaged {
        messages: Vec::new(),
        metadata: Vec::new(),
        attachments: Vec::new(),
        report,
        schemas: BTreeMap::new(),
        channels: BTreeMap::new(),
        channel_order: Vec::new(),
    };
    let push = |header: &mcap::records::MessageHeader, data: &[u8], out: &mut Salvaged| {
        let Some(c) = channels.get(&header.channel_id) else {
            out.report.messages_unattributed += 1;
            return;
        };
        out.messages.push(RecoveredMessage {
            topic: c.topic.clone(),
            schema_name: schemas.get(&c.schema_id).map(|s: &SchemaInfo| s.name.clone()).unwrap_or_default(),
            message_encoding: c.message_encoding.clone(),
            log_time: header.log_time,
            publish_time: header.publish_time,
            sequence: header.sequence,
            data: data.to_vec(),
        });
    };
    for c in &m.chunks {
        if let Ok(recs) = &c.content {
            out.report.chunks_ok += 1;
            for r in recs {
                if let Record::Message { header, data } = r {
                    push(header, data, &mut out);
                }
            }
        } else {
            out.report.chunks_lost += 1;
        }
    }
    // Messages outside chunks count only in a file without chunks (in a chunked file such a
    // record can only be a damaged chunk whose opcode changed).
    let chunked = !m.chunks.is_empty() || m.summary.as_ref().is_some_and(|s| !s.chunk_indexes.is_empty());
    for (_, r) in &m.records {
        match r {
            Record::Message { header, data } if !chunked => push(header, data, &mut out),
            Record::Metadata(md) => match crate::meta::check_episode_record(&md.metadata) {
                Err(e) if crate::meta::CHECKED_RECORDS.contains(&md.name.as_str()) => {
                    out.report.metadata_dropped.push(format!("{}: {e}", md.name));
                }
                _ => out.metadata.push((md.name.clone(), md.metadata.clone())),
            },
            Record::Attachment { header, data, .. } => out.attachments.push(mcap::Attachment {
                log_time: header.log_time,
                create_time: header.create_time,
                name: header.name.clone(),
                media_type: header.media_type.clone(),
                data: std::borrow::Cow::Owned(data.to_vec()),
            }),
            _ => {}
        }
    }
    out.report.lost_chunks = chunk_checks(&m).into_iter().filter(|c| !c.recoverable).collect();
    let mut steps: Vec<u64> =
        out.messages.iter().filter(|x| x.topic == TOPIC_STEP).filter_map(|x| step_number(&x.data)).collect();
    steps.sort_unstable();
    steps.dedup();
    let length = out
        .metadata
        .iter()
        .rev()
        .find(|(n, _)| n == "episode")
        .and_then(|(_, md)| md.get("length")?.parse::<u64>().ok());
    let has_steps = channels.values().any(|c| c.topic == TOPIC_STEP);
    out.report.step_gaps = if has_steps { gaps_of(&steps, length) } else { Vec::new() };
    out.report.bytes_used = m.bytes_used as u64;
    out.report.complete = m.complete && m.summary.is_some() && m.data_end.is_some();
    out.report.stopped_because = m.stopped_because.clone();
    out.report.messages = out.messages.len() as u64;
    out.report.metadata = out.metadata.len() as u64;
    out.report.attachments = out.attachments.len() as u64;
    out.schemas = schemas;
    out.channels = channels;
    out.channel_order = order;
    Ok(out)
}

/// The integrity of an MCAP file, from [`verify`].
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize)]
pub struct VerifyReport {
    /// File size, bytes.
    pub bytes: u64,
    /// Footer, intact summary and Data End record present.
    pub complete: bool,
    /// Every chunk found (intact and damaged), in file order.
    pub chunks: Vec<ChunkCheck>,
    /// Unreadable byte ranges outside any known chunk: `(start, end, reason)`.
    pub skipped: Vec<(u64, u64, String)>,
    /// The data-section CRC of the Data End record matched (`None`: no Data End record, or CRC 0).
    pub data_crc_ok: Option<bool>,
    /// Why the summary could not be used (`None` when it is intact, or the file has no footer).
    pub summary_problem: Option<String>,
    /// Messages in intact chunks.
    pub messages_ok: u64,
    /// Messages in damaged chunks, when every damaged chunk's count is known.
    pub messages_lost: Option<u64>,
    /// Every problem, one line each (empty: the file is healthy).
    pub problems: Vec<String>,
}

impl VerifyReport {
    /// No problem found.
    pub fn is_ok(&self) -> bool {
        self.problems.is_empty()
    }

    /// The chunks that are not intact.
    pub fn damaged_chunks(&self) -> impl Iterator<Item = &ChunkCheck> {
        self.chunks.iter().filter(|c| c.error.is_some())
    }
}

/// Check a demo's bytes: every chunk's CRC, the data-section and summary CRCs, and that the file
/// is complete.
///
/// # Errors
/// [`DemoError::Format`] when the bytes do not start as MCAP (a damaged leading magic is a
/// problem of the report instead).
pub fn verify_bytes(buf: &[u8], name: &Path) -> Result<VerifyReport, DemoError> {
    let start = mcap_start(buf, name)?;
    let m = crate::scan::map_file(buf);
    let chunks = chunk_checks(&m);
    let mut problems = Vec::new();
    if start == Start::DamagedMagic {
        problems.push(crate::scan::damaged_magic_text(buf));
    }
    let secs = |t: u64| t as f64 / 1e9;
    let mut lost = Some(0u64);
    let mut ok = 0u64;
    for c in &chunks {
        if c.recoverable {
            ok += c.messages.unwrap_or(0);
        } else {
            lost = lost.zip(c.messages).map(|(a, b)| a + b);
        }
        if let Some(e) = &c.error {
            let n = match (c.recoverable, c.messages) {
                (true, Some(n)) => format!("{n} messages, recoverable"),
                (false, Some(n)) => format!("{n} messages lost"),
                (_, None) => "message count unknown".into(),
            };
            let t = c
                .log_times
                .map(|(a, b)| format!(", log time {:.3}–{:.3} s", secs(a), secs(b)))
                .unwrap_or_default();
            problems.push(format!("chunk {} at byte {}: {e} ({n}{t})", c.index, c.offset));
        }
    }
    let skipped: Vec<(u64, u64, String)> =
        m.skipped.iter().map(|s| (s.start as u64, s.end as u64, s.reason.clone())).collect();
    for (a, b, why) in &skipped {
        problems.push(format!("bytes {a}..{b} unreadable: {why}"));
    }
    let complete = m.complete && m.summary.is_some() && m.data_end.is_some();
    if !m.complete {
        problems.push("no footer: the file is cut or was never finished".into());
    } else if let Some(p) = &m.summary_problem {
        problems.push(format!("summary not usable: {p}"));
    }
    if m.complete && m.data_end.is_none() {
        problems.push("no Data End record before the summary".into());
    }
    if m.data_crc_ok == Some(false) && chunks.iter().all(|c| c.error.is_none()) && skipped.is_empty() {
        problems.push(
            "data section CRC mismatch: bytes outside the chunks' own CRCs (metadata, message indexes, \
             chunk headers) are damaged"
                .into(),
        );
    }
    if let Some(st) = m.summary.as_ref().and_then(|s| s.statistics.as_ref()) {
        if lost == Some(0) && st.message_count != ok {
            problems.push(format!("summary counts {} messages, the chunks hold {ok}", st.message_count));
        }
    }
    for (offset, r) in &m.records {
        if let Record::Metadata(md) = r
            && crate::meta::CHECKED_RECORDS.contains(&md.name.as_str())
            && let Err(e) = crate::meta::check_episode_record(&md.metadata)
        {
            problems.push(format!("metadata record \"{}\" at byte {offset}: {e}", md.name));
        }
    }
    Ok(VerifyReport {
        bytes: buf.len() as u64,
        complete,
        chunks,
        skipped,
        data_crc_ok: m.data_crc_ok,
        summary_problem: m.summary_problem,
        messages_ok: ok,
        messages_lost: lost,
        problems,
    })
}

/// How `buf` starts, or [`DemoError::Format`] when it is not MCAP at all.
fn mcap_start(buf: &[u8], name: &Path) -> Result<Start, DemoError> {
    match crate::scan::file_start(buf) {
        Start::NotMcap => {
            Err(DemoError::Format { path: name.to_path_buf(), reason: "not an MCAP file (bad magic)".into() })
        }
        s => Ok(s),
    }
}

/// [`verify_bytes`] of a file.
///
/// # Errors
/// [`DemoError::Io`] if it cannot be read; [`DemoError::Format`] if it is not MCAP at all.
pub fn verify(path: impl AsRef<Path>) -> Result<VerifyReport, DemoError> {
    let path = path.as_ref();
    let buf = crate::read_input(path)?;
    verify_bytes(&buf, path)
}

/// Recover every complete message of a (possibly cut) demo file.
///
/// # Errors
/// [`DemoError::Io`] if the file cannot be read; [`DemoError::Format`] if it is not MCAP at all.
pub fn salvage(path: impl AsRef<Path>) -> Result<(Vec<RecoveredMessage>, SalvageReport), DemoError> {
    let path = path.as_ref();
    let buf = crate::read_input(path)?;
    let s = salvage_bytes(&buf, path)?;
    Ok((s.messages, s.report))
}

/// Recover a (possibly cut or damaged) demo and write what was recovered as a valid, complete
/// MCAP file (same schema and channel ids, messages, metadata records and attachments; zstd
/// chunks). Adds a `salvage` metadata record saying how much was recovered, with `step_gaps`
/// (the missing step ranges `a..b,c..d`, half-open) and `lost_chunks` (`index@offset:t0..t1ns`),
/// so that [`crate::read_demo`] loads the result. `path_out` may not equal `path_in`.
///
/// # Errors
/// As [`salvage`]; [`DemoError::Format`] when nothing recognisable as a demo survives (no
/// `/demo/step` channel and no sign that demo-log wrote the file), instead of writing a file the
/// reader would refuse; [`DemoError::Mcap`]/[`DemoError::Io`] when writing fails.
pub fn salvage_to(path_in: impl AsRef<Path>, path_out: impl AsRef<Path>) -> Result<SalvageReport, DemoError> {
    let (path_in, path_out) = (path_in.as_ref(), path_out.as_ref());
    let buf = crate::read_input(path_in)?;
    let s = salvage_bytes(&buf, path_in)?;
    if !s.channels.values().any(|c| c.topic == TOPIC_STEP) {
        return Err(DemoError::Format {
            path: path_in.to_path_buf(),
            reason: format!(
                "nothing recognisable as a demo survives (no {TOPIC_STEP} channel, and neither the MCAP header, \
                 the episode metadata nor any intact step message says it was written by demo-log); \
                 {} messages recovered",
                s.report.messages
            ),
        });
    }
    let tmp: PathBuf = crate::partial_path(path_out);
    let file = std::fs::File::create(&tmp).map_err(|e| DemoError::Io { path: tmp.clone(), source: e })?;
    let me = |e| DemoError::Mcap { path: path_out.to_path_buf(), source: e };
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .compression_threads(0)
        .chunk_size(Some(256 * 1024))
        .library(format!("mimicrete-demo-log/{} (salvage)", env!("CARGO_PKG_VERSION")))
        .create(std::io::BufWriter::new(file))
        .map_err(me)?;
    // The original ids are kept, so that a salvaged demo has the writer's layout again.
    let mut schema_map = BTreeMap::new();
    for (&id, sc) in &s.schemas {
        schema_map.insert(id, w.add_schema_with_id(id, &sc.name, &sc.encoding, &sc.data).map_err(me)?);
    }
    let mut chan_map = BTreeMap::new();
    for id in &s.channel_order {
        let c = &s.channels[id];
        let sid = if c.schema_id == 0 { 0 } else { schema_map.get(&c.schema_id).copied().unwrap_or(0) };
        chan_map.insert(
            c.topic.clone(),
            w.add_channel_with_id(*id, sid, &c.topic, &c.message_encoding, &c.metadata).map_err(me)?,
        );
    }
    for (name, md) in &s.metadata {
        w.write_metadata(&mcap::records::Metadata { name: name.clone(), metadata: md.clone() })
            .map_err(me)?;
    }
    // The `salvage` record comes last among the metadata (a file salvaged twice keeps both; the
    // last one counts) and before the messages.
    let r = &s.report;
    let mut md = BTreeMap::new();
    md.insert("source".to_string(), path_in.display().to_string());
    md.insert("bytes_total".to_string(), r.bytes_total.to_string());
    md.insert("bytes_used".to_string(), r.bytes_used.to_string());
    md.insert("chunks_ok".to_string(), r.chunks_ok.to_string());
    md.insert("chunks_lost".to_string(), r.chunks_lost.to_string());
    md.insert("messages".to_string(), r.messages.to_string());
    md.insert("complete".to_string(), r.complete.to_string());
    md.insert("step_gaps".to_string(), format_gaps(&r.step_gaps));
    md.insert("layout_assumed".to_string(), r.layout_assumed.to_string());
    md.insert("metadata_dropped".to_string(), r.metadata_dropped.join("; "));
    let lost: Vec<String> = r
        .lost_chunks
        .iter()
        .map(|c| match c.log_times {
            Some((a, b)) => format!("{}@{}:{a}..{b}ns", c.index, c.offset),
            None => format!("{}@{}", c.index, c.offset),
        })
        .collect();
    md.insert("lost_chunks".to_string(), lost.join(","));
    w.write_metadata(&mcap::records::Metadata { name: "salvage".into(), metadata: md }).map_err(me)?;
    for a in &s.attachments {
        w.attach(a).map_err(me)?;
    }
    for m in &s.messages {
        let channel_id = chan_map[&m.topic];
        w.write_to_known_channel(
            &mcap::records::MessageHeader {
                channel_id,
                sequence: m.sequence,
                log_time: m.log_time,
                publish_time: m.publish_time,
            },
            &m.data,
        )
        .map_err(me)?;
    }
    w.finish().map_err(me)?;
    let f = w
        .into_inner()
        .into_inner()
        .map_err(|e| DemoError::Io { path: tmp.clone(), source: e.into_error() })?;
    f.sync_all().map_err(|e| DemoError::Io { path: tmp.clone(), source: e })?;
    drop(f);
    std::fs::rename(&tmp, path_out).map_err(|e| DemoError::Io { path: path_out.to_path_buf(), source: e })?;
    Ok(s.report)
}
