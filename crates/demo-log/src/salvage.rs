//! Recovery of demos cut off mid-write (crash, full disk, killed process).
//!
//! The file is scanned record by record from the start. Every complete chunk whose CRC checks
//! gives back all its messages; a chunk that is cut or damaged is lost whole (the writer closes
//! chunks at least every `flush_every_steps` steps, so little is at risk) and scanning goes on after
//! it when its length is intact. Metadata records and attachments before the cut are kept.

use crate::DemoError;
use mcap::records::Record;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A message recovered from a damaged file.
#[derive(Debug, Clone, PartialEq, Eq)]
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
    pub data: Vec<u8>,
}

/// What salvage found.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize)]
pub struct SalvageReport {
    /// Size of the input, bytes.
    pub bytes_total: u64,
    /// Offset just past the last record that was read whole.
    pub bytes_used: u64,
    /// Complete chunks whose messages were recovered.
    pub chunks_ok: u64,
    /// Chunks lost (cut at the end, or damaged).
    pub chunks_lost: u64,
    /// Messages recovered.
    pub messages: u64,
    /// Metadata records recovered.
    pub metadata: u64,
    /// Attachments recovered.
    pub attachments: u64,
    /// The input was already a complete MCAP file (footer and end magic present).
    pub complete: bool,
    /// Why reading stopped early, if it did.
    pub stopped_because: Option<String>,
}

struct SchemaInfo {
    name: String,
    encoding: String,
    data: Vec<u8>,
}

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

const MAGIC: &[u8] = b"\x89MCAP0\r\n";

fn handle_inner(
    rec: Record<'_>,
    out: &mut Salvaged,
    schemas: &mut BTreeMap<u16, SchemaInfo>,
    channels: &mut BTreeMap<u16, ChannelInfo>,
    channel_order: &mut Vec<u16>,
) {
    match rec {
        Record::Schema { header, data } => {
            schemas.entry(header.id).or_insert(SchemaInfo {
                name: header.name,
                encoding: header.encoding,
                data: data.into_owned(),
            });
        }
        Record::Channel(c) => {
            if let std::collections::btree_map::Entry::Vacant(v) = channels.entry(c.id) {
                channel_order.push(c.id);
                v.insert(ChannelInfo {
                    topic: c.topic,
                    schema_id: c.schema_id,
                    message_encoding: c.message_encoding,
                    metadata: c.metadata,
                });
            }
        }
        Record::Message { header, data } => {
            let (topic, enc, schema_name) = match channels.get(&header.channel_id) {
                Some(c) => (
                    c.topic.clone(),
                    c.message_encoding.clone(),
                    schemas.get(&c.schema_id).map(|s| s.name.clone()).unwrap_or_default(),
                ),
                // A message whose channel record was lost cannot be attributed; skip it.
                None => return,
            };
            out.messages.push(RecoveredMessage {
                topic,
                schema_name,
                message_encoding: enc,
                log_time: header.log_time,
                publish_time: header.publish_time,
                sequence: header.sequence,
                data: data.into_owned(),
            });
        }
        Record::Metadata(m) => out.metadata.push((m.name, m.metadata)),
        Record::Attachment { header, data, .. } => out.attachments.push(mcap::Attachment {
            log_time: header.log_time,
            create_time: header.create_time,
            name: header.name,
            media_type: header.media_type,
            data: std::borrow::Cow::Owned(data.into_owned()),
        }),
        _ => {}
    }
}

/// Recover everything complete from the bytes of a (possibly cut) MCAP file.
///
/// # Errors
/// [`DemoError::Format`] when the bytes do not start with the MCAP magic.
pub fn salvage_bytes(buf: &[u8], name: &Path) -> Result<Salvaged, DemoError> {
    if buf.len() < MAGIC.len() || &buf[..MAGIC.len()] != MAGIC {
        return Err(DemoError::Format {
            path: name.to_path_buf(),
            reason: "not an MCAP file (bad magic)".into(),
        });
    }
    let mut out = Salvaged {
        messages: Vec::new(),
        metadata: Vec::new(),
        attachments: Vec::new(),
        report: SalvageReport { bytes_total: buf.len() as u64, ..Default::default() },
        schemas: BTreeMap::new(),
        channels: BTreeMap::new(),
        channel_order: Vec::new(),
    };
    let mut schemas = BTreeMap::new();
    let mut channels = BTreeMap::new();
    let mut order = Vec::new();
    // Walk the top-level records by their length prefixes ourselves so that a damaged chunk can be
    // skipped and the exact end of the last whole record is known.
    let mut pos = MAGIC.len();
    let mut in_summary = false;
    loop {
        if pos == buf.len() {
            out.report.stopped_because = Some("end of data before the footer".into());
            break;
        }
        if buf.len() - pos < 9 {
            // Either the end magic (complete file) or a cut record header.
            if &buf[pos..] == MAGIC && in_summary {
                out.report.complete = true;
                out.report.bytes_used = buf.len() as u64;
            } else {
                out.report.stopped_because = Some(format!("cut inside a record header at byte {pos}"));
            }
            break;
        }
        let op = buf[pos];
        let len = u64::from_le_bytes(buf[pos + 1..pos + 9].try_into().expect("8 bytes"));
        let body_start = pos + 9;
        let Some(body_end) = (body_start as u64).checked_add(len).filter(|&e| e <= buf.len() as u64) else {
            if op == mcap::records::op::CHUNK {
                out.report.chunks_lost += 1;
            }
            out.report.stopped_because = Some(format!(
                "record (opcode 0x{op:02x}) at byte {pos} is cut: {len} bytes announced, {} left",
                buf.len() - body_start
            ));
            break;
        };
        let body_end = body_end as usize;
        let body = &buf[body_start..body_end];
        if !crate::scan::is_parsed_kind(op) {
            pos = body_end;
            out.report.bytes_used = pos as u64;
            continue;
        }
        let parsed = crate::scan::parse_checked(op, body);
        match parsed {
            Ok(Record::Chunk { header, data }) => {
                let decoded = crate::scan::decode_chunk(&header, &data);
                match decoded.as_deref().map_err(|e| e.clone()).and_then(|d| crate::scan::chunk_records(d)) {
                    Ok(inner) => {
                        out.report.chunks_ok += 1;
                        for r in inner {
                            handle_inner(r, &mut out, &mut schemas, &mut channels, &mut order);
                        }
                    }
                    Err(e) => {
                        out.report.chunks_lost += 1;
                        if out.report.stopped_because.is_none() {
                            out.report.stopped_because = Some(format!("damaged chunk at byte {pos}: {e}"));
                        }
                    }
                }
            }
            Ok(Record::DataEnd(_)) => in_summary = true,
            Ok(Record::Footer(_)) => {
                in_summary = true;
            }
            Ok(r @ (Record::Schema { .. } | Record::Channel(_))) => {
                if !in_summary {
                    handle_inner(r, &mut out, &mut schemas, &mut channels, &mut order);
                }
            }
            Ok(r @ (Record::Metadata(_) | Record::Attachment { .. } | Record::Message { .. })) => {
                handle_inner(r, &mut out, &mut schemas, &mut channels, &mut order);
            }
            Ok(_) => {}
            Err(e) => {
                // A whole record that does not parse: skip it by its length.
                if op == mcap::records::op::CHUNK {
                    out.report.chunks_lost += 1;
                }
                if out.report.stopped_because.is_none() {
                    out.report.stopped_because = Some(format!("damaged record at byte {pos}: {e}"));
                }
            }
        }
        pos = body_end;
        out.report.bytes_used = pos as u64;
    }
    out.report.messages = out.messages.len() as u64;
    out.report.metadata = out.metadata.len() as u64;
    out.report.attachments = out.attachments.len() as u64;
    out.schemas = schemas;
    out.channels = channels;
    out.channel_order = order;
    Ok(out)
}

/// Recover every complete message of a (possibly cut) demo file.
///
/// # Errors
/// [`DemoError::Io`] if the file cannot be read; [`DemoError::Format`] if it is not MCAP at all.
pub fn salvage(path: impl AsRef<Path>) -> Result<(Vec<RecoveredMessage>, SalvageReport), DemoError> {
    let path = path.as_ref();
    let buf = std::fs::read(path).map_err(|e| DemoError::Io { path: path.to_path_buf(), source: e })?;
    let s = salvage_bytes(&buf, path)?;
    Ok((s.messages, s.report))
}

/// Recover a (possibly cut) demo and write what was recovered as a valid, complete MCAP file
/// (same schemas, channels, messages, metadata records and attachments; zstd chunks). Adds a
/// `salvage` metadata record saying how much was recovered. `path_out` may not equal `path_in`.
///
/// # Errors
/// As [`salvage`], plus [`DemoError::Mcap`]/[`DemoError::Io`] when writing fails.
pub fn salvage_to(path_in: impl AsRef<Path>, path_out: impl AsRef<Path>) -> Result<SalvageReport, DemoError> {
    let (path_in, path_out) = (path_in.as_ref(), path_out.as_ref());
    let buf = std::fs::read(path_in).map_err(|e| DemoError::Io { path: path_in.to_path_buf(), source: e })?;
    let s = salvage_bytes(&buf, path_in)?;
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
    let mut schema_map = BTreeMap::new();
    for (&id, sc) in &s.schemas {
        schema_map.insert(id, w.add_schema(&sc.name, &sc.encoding, &sc.data).map_err(me)?);
    }
    let mut chan_map = BTreeMap::new();
    for id in &s.channel_order {
        let c = &s.channels[id];
        let sid = if c.schema_id == 0 { 0 } else { schema_map.get(&c.schema_id).copied().unwrap_or(0) };
        chan_map.insert(
            c.topic.clone(),
            w.add_channel(sid, &c.topic, &c.message_encoding, &c.metadata).map_err(me)?,
        );
    }
    for (name, md) in &s.metadata {
        w.write_metadata(&mcap::records::Metadata { name: name.clone(), metadata: md.clone() })
            .map_err(me)?;
    }
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
    let r = &s.report;
    let mut md = BTreeMap::new();
    md.insert("source".to_string(), path_in.display().to_string());
    md.insert("bytes_total".to_string(), r.bytes_total.to_string());
    md.insert("bytes_used".to_string(), r.bytes_used.to_string());
    md.insert("chunks_ok".to_string(), r.chunks_ok.to_string());
    md.insert("chunks_lost".to_string(), r.chunks_lost.to_string());
    md.insert("messages".to_string(), r.messages.to_string());
    md.insert("complete".to_string(), r.complete.to_string());
    w.write_metadata(&mcap::records::Metadata { name: "salvage".into(), metadata: md }).map_err(me)?;
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
