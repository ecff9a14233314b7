//! Safe chunk decoding shared by the reader and salvage: decompress with a size cap, check the
//! CRC, and only then parse the records inside, with record lengths bounded by the chunk.

use mcap::records::{ChunkHeader, Record};

/// Largest uncompressed chunk accepted (the writer's chunks are 64 KiB).
pub const MAX_CHUNK: u64 = 256 * 1024 * 1024;

/// Decompress a chunk's data and verify its CRC.
pub fn decode_chunk(header: &ChunkHeader, data: &[u8]) -> Result<Vec<u8>, String> {
    if header.uncompressed_size > MAX_CHUNK {
        return Err(format!(
            "chunk claims {} uncompressed bytes (limit {MAX_CHUNK})",
            header.uncompressed_size
        ));
    }
    let n = header.uncompressed_size as usize;
    let out = match header.compression.as_str() {
        "" => data.to_vec(),
        "zstd" => zstd::bulk::decompress(data, n).map_err(|e| format!("zstd: {e}"))?,
        other => return Err(format!("unsupported chunk compression \"{other}\"")),
    };
    if out.len() != n {
        return Err(format!("chunk decompressed to {} bytes, header says {n}", out.len()));
    }
    if header.uncompressed_crc != 0 {
        let crc = crc32fast::hash(&out);
        if crc != header.uncompressed_crc {
            return Err(format!("chunk CRC mismatch: {crc:08x} != {:08x}", header.uncompressed_crc));
        }
    }
    Ok(out)
}

/// The records inside a decoded chunk, all or nothing (kinds this crate does not use are skipped).
pub fn chunk_records(decoded: &[u8]) -> Result<Vec<Record<'_>>, String> {
    let mut v = Vec::new();
    for_each_record(decoded, |op, body| {
        if is_parsed_kind(op) {
            v.push(parse_checked(op, body)?);
        }
        Ok(())
    })?;
    Ok(v)
}

/// Walk the records of a decoded chunk without copying: `f(opcode, body)`. All-or-nothing on
/// framing: a record that runs past the end is an error (reported before `f` sees it).
pub fn for_each_record<'a>(
    decoded: &'a [u8],
    mut f: impl FnMut(u8, &'a [u8]) -> Result<(), String>,
) -> Result<(), String> {
    let mut pos = 0usize;
    while pos < decoded.len() {
        if decoded.len() - pos < 9 {
            return Err(format!("record header cut at chunk offset {pos}"));
        }
        let op = decoded[pos];
        let len = u64::from_le_bytes(decoded[pos + 1..pos + 9].try_into().expect("8 bytes"));
        let start = pos + 9;
        if len > (decoded.len() - start) as u64 {
            return Err(format!("record at chunk offset {pos} runs past the chunk"));
        }
        let end = start + len as usize;
        f(op, &decoded[start..end])?;
        pos = end;
    }
    Ok(())
}

/// A message record's channel id and payload (`None` if the body is too short).
pub fn message_parts(body: &[u8]) -> Option<(u16, &[u8])> {
    // channel_id u16, sequence u32, log_time u64, publish_time u64, then data.
    if body.len() < 22 {
        return None;
    }
    Some((u16::from_le_bytes([body[0], body[1]]), &body[22..]))
}

/// Cursor over a record body that checks every length prefix against the bytes left.
struct Check<'a> {
    b: &'a [u8],
    pos: usize,
}

impl Check<'_> {
    fn take(&mut self, n: u64) -> Option<()> {
        let left = (self.b.len() - self.pos) as u64;
        if n > left {
            return None;
        }
        self.pos += n as usize;
        Some(())
    }
    fn u32(&mut self) -> Option<u32> {
        let v = self.b.get(self.pos..self.pos + 4)?;
        self.pos += 4;
        Some(u32::from_le_bytes(v.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        let v = self.b.get(self.pos..self.pos + 8)?;
        self.pos += 8;
        Some(u64::from_le_bytes(v.try_into().ok()?))
    }
    fn str(&mut self) -> Option<()> {
        let n = self.u32()?;
        self.take(n as u64)
    }
    fn string_map(&mut self) -> Option<()> {
        let n = self.u32()? as u64;
        let end = self.pos as u64 + n;
        if end > self.b.len() as u64 {
            return None;
        }
        while (self.pos as u64) < end {
            self.str()?;
            self.str()?;
        }
        (self.pos as u64 == end).then_some(())
    }
}

/// Whether every length prefix of a record body fits inside it, for the record kinds this crate
/// parses (Header, Footer, Schema, Channel, Message, Chunk, Attachment, Metadata, DataEnd). mcap
/// 0.26 reserves memory for a string from its length prefix before reading it, so a corrupt prefix
/// would otherwise ask for gigabytes (found by cargo fuzz).
pub fn plausible(op: u8, body: &[u8]) -> bool {
    fields_end(op, body).is_some()
}

/// Where the fields of a record body end, if every length prefix fits (see [`plausible`]);
/// message index records are included.
fn fields_end(op: u8, body: &[u8]) -> Option<usize> {
    use mcap::records::op;
    let mut c = Check { b: body, pos: 0 };
    match op {
        op::HEADER => c.str().and_then(|_| c.str()),
        op::FOOTER => c.take(20),
        op::SCHEMA => c.take(2).and_then(|_| c.str()).and_then(|_| c.str()).and_then(|_| c.str()),
        op::CHANNEL => c.take(4).and_then(|_| c.str()).and_then(|_| c.str()).and_then(|_| c.string_map()),
        op::MESSAGE => c.take(body.len().max(22) as u64),
        op::CHUNK => c.take(28).and_then(|_| c.str()).and_then(|_| {
            let n = c.u64()?;
            c.take(n)
        }),
        op::ATTACHMENT => c.take(16).and_then(|_| c.str()).and_then(|_| c.str()).and_then(|_| {
            let n = c.u64()?;
            c.take(n)?;
            c.take(4)
        }),
        op::METADATA => c.str().and_then(|_| c.string_map()),
        op::DATA_END => c.take(4),
        op::MESSAGE_INDEX => c.take(2).and_then(|_| {
            let n = c.u32()? as u64;
            (n % 16 == 0).then_some(())?;
            c.take(n)
        }),
        _ => None,
    }
    .map(|_| c.pos)
}

/// [`mcap::parse_record`] after [`plausible`].
pub fn parse_checked(op: u8, body: &[u8]) -> Result<Record<'_>, String> {
    if !plausible(op, body) {
        return Err(format!("malformed record (opcode 0x{op:02x}): a length prefix runs past the record"));
    }
    mcap::parse_record(op, body).map_err(|e| e.to_string())
}

/// The opcodes [`plausible`] knows.
pub fn is_parsed_kind(op: u8) -> bool {
    use mcap::records::op;
    matches!(
        op,
        op::HEADER
            | op::FOOTER
            | op::SCHEMA
            | op::CHANNEL
            | op::MESSAGE
            | op::CHUNK
            | op::ATTACHMENT
            | op::METADATA
            | op::DATA_END
    )
}

/// The MCAP magic, at both ends of a file.
pub const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// How a file starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Start {
    /// With the MCAP magic.
    Magic,
    /// With the MCAP magic damaged (at most two of its bytes differ) but the rest says MCAP: a
    /// whole Header record follows it, or the file ends with the magic.
    DamagedMagic,
    /// Not as an MCAP file.
    NotMcap,
}

/// Whether `buf` starts as an MCAP file (see [`Start`]): one flipped bit in the leading magic
/// should not hide every intact chunk behind it.
pub fn file_start(buf: &[u8]) -> Start {
    let n = MAGIC.len();
    if buf.len() < n {
        return Start::NotMcap;
    }
    if &buf[..n] == MAGIC {
        return Start::Magic;
    }
    let differing = buf[..n].iter().zip(MAGIC).filter(|(a, b)| a != b).count();
    let header_follows = matches!(frame(buf, n, buf.len()), Ok((op, start, end))
        if op == mcap::records::op::HEADER && exact(op, &buf[start..end]));
    let ends_as_mcap = buf.len() >= 2 * n && &buf[buf.len() - n..] == MAGIC;
    if differing <= 2 && (header_follows || ends_as_mcap) { Start::DamagedMagic } else { Start::NotMcap }
}

/// Text of a problem with the leading magic (for [`Start::DamagedMagic`]).
pub fn damaged_magic_text(buf: &[u8]) -> String {
    let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<Vec<_>>().join(" ");
    format!(
        "the leading magic is damaged (bytes 0..8 are {}, MCAP's are {})",
        hex(&buf[..MAGIC.len().min(buf.len())]),
        hex(MAGIC)
    )
}

/// Whether a record body is consumed exactly by its fields, as every MCAP v0 writer writes them: a
/// bit flip in a record's length would otherwise shift the framing silently (a Header whose
/// length grew swallowing the chunks after it, found by the `salvage_damage` fuzz target).
fn exact(op: u8, body: &[u8]) -> bool {
    fields_end(op, body) == Some(body.len())
}

/// `(opcode, body start, record end)` of the record at `pos` if its header and body fit before
/// `limit`.
fn frame(buf: &[u8], pos: usize, limit: usize) -> Result<(u8, usize, usize), String> {
    if limit < pos + 9 {
        return Err(format!("record header cut at byte {pos}"));
    }
    let op = buf[pos];
    let len = u64::from_le_bytes(buf[pos + 1..pos + 9].try_into().expect("8 bytes"));
    let start = pos + 9;
    if len > (limit - start) as u64 {
        return Err(format!(
            "record (opcode 0x{op:02x}) at byte {pos} announces {len} bytes, only {} left",
            limit - start
        ));
    }
    Ok((op, start, start + len as usize))
}

/// A chunk decoded and checked: its inner records parse and its CRC matches.
pub struct GoodChunk<'a> {
    /// The chunk header (its log-time fields are not covered by the CRC).
    pub header: ChunkHeader,
    /// The records inside.
    pub records: Vec<Record<'a>>,
    /// Number of Message records inside.
    pub messages: u64,
    /// Smallest and largest log time of its messages.
    pub log_times: Option<(u64, u64)>,
}

/// Why a chunk could not be read, with what is known of it.
pub struct BadChunk {
    /// The chunk header, when it parses.
    pub header: Option<ChunkHeader>,
    /// What is wrong.
    pub reason: String,
}

/// Decode the chunk record `body` (its CRC checked, then every record inside parsed) into owned
/// records.
fn good_chunk(body: &[u8]) -> Result<GoodChunk<'static>, (Option<ChunkHeader>, String)> {
    if !exact(mcap::records::op::CHUNK, body) {
        return Err((None, "chunk fields do not add up to the record length".into()));
    }
    let Ok(Record::Chunk { header, data }) = parse_checked(mcap::records::op::CHUNK, body) else {
        return Err((None, "chunk header does not parse".into()));
    };
    let decoded = decode_chunk(&header, &data).map_err(|e| (Some(header.clone()), e))?;
    let records = chunk_records(&decoded).map_err(|e| (Some(header.clone()), e))?;
    let mut messages = 0;
    let mut log_times: Option<(u64, u64)> = None;
    let records: Vec<Record<'static>> = records
        .into_iter()
        .map(|r| {
            if let Record::Message { header: h, .. } = &r {
                messages += 1;
                let t = h.log_time;
                log_times = Some(log_times.map_or((t, t), |(a, b)| (a.min(t), b.max(t))));
            }
            r.into_owned()
        })
        .collect();
    Ok(GoodChunk { header, records, messages, log_times })
}

/// The chunk record at `pos`: `Ok` when whole and intact, else what is known of it.
pub fn chunk_at(buf: &[u8], pos: usize, limit: usize) -> Result<(GoodChunk<'static>, usize), BadChunk> {
    let (op, start, end) = match frame(buf, pos, limit) {
        Ok(f) => f,
        Err(reason) => {
            // A cut chunk: its fixed header fields may still be there.
            let header = (buf.len() >= pos + 9 + 32)
                .then(|| {
                    let b = &buf[pos + 9..];
                    let u = |i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
                    ChunkHeader {
                        message_start_time: u(0),
                        message_end_time: u(8),
                        uncompressed_size: u(16),
                        uncompressed_crc: 0,
                        compression: String::new(),
                        compressed_size: 0,
                    }
                })
                .filter(|_| buf.get(pos) == Some(&mcap::records::op::CHUNK));
            return Err(BadChunk { header, reason });
        }
    };
    if op != mcap::records::op::CHUNK {
        return Err(BadChunk { header: None, reason: format!("opcode 0x{op:02x}, not a chunk") });
    }
    good_chunk(&buf[start..end]).map(|g| (g, end)).map_err(|(header, reason)| BadChunk { header, reason })
}

/// Whether a whole, CRC-checked chunk record (with a non-zero CRC) starts at `pos`: the test used
/// to find the next intact chunk after damage.
fn is_sync_chunk(buf: &[u8], pos: usize, limit: usize) -> bool {
    let Ok((_, start, end)) = frame(buf, pos, limit) else { return false };
    let body = &buf[start..end];
    // uncompressed_crc sits after the two times and the size; a zero CRC proves nothing.
    body.len() >= 28 && body[24..28] != [0, 0, 0, 0] && good_chunk(body).is_ok()
}

/// Whether an attachment record with a matching non-zero CRC starts at `pos`.
fn is_sync_attachment(buf: &[u8], pos: usize, limit: usize) -> bool {
    let Ok((op, start, end)) = frame(buf, pos, limit) else { return false };
    let body = &buf[start..end];
    op == mcap::records::op::ATTACHMENT
        && body.len() >= 4
        && body[body.len() - 4..] != [0, 0, 0, 0]
        && parse_checked(op, body).is_ok()
}

/// A chunk of a file, intact or not.
pub struct ChunkSlot {
    /// Offset of its opcode byte.
    pub offset: usize,
    /// End of its record, when known.
    pub end: Option<usize>,
    /// Log-time range: from its messages when intact, else from its header or the summary's
    /// chunk index.
    pub log_times: Option<(u64, u64)>,
    /// Messages in it: counted when intact, else from the message index records after it.
    pub messages: Option<u64>,
    /// The decoded chunk, or why it cannot be read.
    pub content: Result<Vec<Record<'static>>, String>,
    /// Its header's log-time fields (not covered by the CRC) disagree with its messages.
    pub header_times_wrong: bool,
}

/// Bytes of the data section that could not be read as records and were skipped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Skipped {
    /// First byte.
    pub start: usize,
    /// One past the last byte.
    pub end: usize,
    /// Why reading stopped at `start`.
    pub reason: String,
}

/// The summary section, read only when its CRC matches (or is absent) and every record parses.
#[derive(Default)]
pub struct SummaryInfo {
    /// Offset of the summary section.
    pub start: usize,
    /// Schema and Channel records.
    pub records: Vec<Record<'static>>,
    /// Chunk indexes.
    pub chunk_indexes: Vec<mcap::records::ChunkIndex>,
    /// Metadata indexes.
    pub metadata_indexes: Vec<mcap::records::MetadataIndex>,
    /// Attachment indexes.
    pub attachment_indexes: Vec<mcap::records::AttachmentIndex>,
    /// Statistics.
    pub statistics: Option<mcap::records::Statistics>,
}

/// Everything found in an MCAP file, damaged or not: the result of [`map_file`].
pub struct FileMap {
    /// Top-level records of the data section other than chunks (Header, Schema, Channel, Message,
    /// Metadata, Attachment) with their offsets, including records found through the summary's
    /// indexes.
    pub records: Vec<(usize, Record<'static>)>,
    /// Every chunk found, by offset.
    pub chunks: Vec<ChunkSlot>,
    /// Unreadable byte ranges of the data section that are not part of a known chunk.
    pub skipped: Vec<Skipped>,
    /// Offset and CRC of the Data End record.
    pub data_end: Option<(usize, u32)>,
    /// The data section CRC matched (`None`: no Data End record or a zero CRC).
    pub data_crc_ok: Option<bool>,
    /// The summary, when present and intact.
    pub summary: Option<SummaryInfo>,
    /// Why the summary was not used, when the file has a footer.
    pub summary_problem: Option<String>,
    /// Footer and end magic present.
    pub complete: bool,
    /// Offset just past the last record read whole.
    pub bytes_used: usize,
    /// Why the walk of the data section ended before a Data End record.
    pub stopped_because: Option<String>,
}

const FOOTER_LEN: usize = 9 + 20;
const NO_SUMMARY: &str = "the file has no summary section";
const NO_SUMMARY_CRC: &str = "the summary has no CRC";

/// What is wrong with the summary section of a file that has a footer, if it is damaged
/// (a CRC mismatch, a record that does not parse, a footer pointing outside the file); a file
/// without a summary or whose summary has no CRC is not damaged. The statistics' message count,
/// when the summary is intact.
pub fn summary_check(buf: &[u8]) -> (Option<String>, Option<u64>) {
    let (_, info, problem) = read_summary(buf);
    let problem = problem.filter(|p| p != NO_SUMMARY && p != NO_SUMMARY_CRC);
    (problem, info.and_then(|i| i.statistics).map(|st| st.message_count))
}

/// Read the footer and, if intact, the summary section.
fn read_summary(buf: &[u8]) -> (bool, Option<SummaryInfo>, Option<String>) {
    use mcap::records::op;
    let n = buf.len();
    if n < 2 * MAGIC.len() + FOOTER_LEN || &buf[n - MAGIC.len()..] != MAGIC {
        return (false, None, None);
    }
    let fpos = n - MAGIC.len() - FOOTER_LEN;
    let Ok((fop, fstart, fend)) = frame(buf, fpos, n - MAGIC.len()) else {
        return (false, None, Some("footer does not parse".into()));
    };
    if fop != op::FOOTER || fend != n - MAGIC.len() {
        return (false, None, Some("no footer before the end magic".into()));
    }
    let f = &buf[fstart..fend];
    let summary_start = u64::from_le_bytes(f[0..8].try_into().expect("8 bytes"));
    let crc = u32::from_le_bytes(f[16..20].try_into().expect("4 bytes"));
    if summary_start == 0 {
        return (true, None, Some(NO_SUMMARY.into()));
    }
    if summary_start < MAGIC.len() as u64 || summary_start > fpos as u64 {
        return (
            true,
            None,
            Some(format!("footer points the summary at byte {summary_start}, outside the file")),
        );
    }
    let s = summary_start as usize;
    if crc == 0 {
        // Without a CRC nothing in the summary can be trusted to point at the right bytes.
        return (true, None, Some(NO_SUMMARY_CRC.into()));
    }
    let got = crc32fast::hash(&buf[s..fpos + 9 + 16]);
    if got != crc {
        return (true, None, Some(format!("summary CRC mismatch: {got:08x} != {crc:08x}")));
    }
    let mut info = SummaryInfo { start: s, ..Default::default() };
    let mut pos = s;
    while pos < fpos {
        let (op, start, end) = match frame(buf, pos, fpos) {
            Ok(f) => f,
            Err(e) => return (true, None, Some(format!("summary: {e}"))),
        };
        let body = &buf[start..end];
        let rec = match op {
            op::SCHEMA
            | op::CHANNEL
            | op::CHUNK_INDEX
            | op::METADATA_INDEX
            | op::ATTACHMENT_INDEX
            | op::STATISTICS => {
                if !matches!(op, op::CHUNK_INDEX | op::METADATA_INDEX | op::ATTACHMENT_INDEX | op::STATISTICS)
                    && !plausible(op, body)
                {
                    return (true, None, Some(format!("summary: malformed record at byte {pos}")));
                }
                match mcap::parse_record(op, body) {
                    Ok(r) => r.into_owned(),
                    Err(e) => return (true, None, Some(format!("summary: record at byte {pos}: {e}"))),
                }
            }
            _ => {
                pos = end;
                continue;
            }
        };
        match rec {
            Record::ChunkIndex(c) => info.chunk_indexes.push(c),
            Record::MetadataIndex(m) => info.metadata_indexes.push(m),
            Record::AttachmentIndex(a) => info.attachment_indexes.push(a),
            Record::Statistics(st) => info.statistics = Some(st),
            r => info.records.push(r),
        }
        pos = end;
    }
    (true, Some(info), None)
}

/// Whether a metadata record whose lengths add up exactly and whose strings are UTF-8 starts at
/// `pos` (in a random position an 8-byte length that fits and nested lengths that add up are
/// already unlikely; metadata records are never inside chunks).
fn is_sync_metadata(buf: &[u8], pos: usize, limit: usize) -> bool {
    let Ok((op, start, end)) = frame(buf, pos, limit) else { return false };
    let body = &buf[start..end];
    op == mcap::records::op::METADATA
        && exact(op, body)
        && matches!(parse_checked(op, body), Ok(Record::Metadata(m)) if !m.name.is_empty())
}

/// Look for the next place reading can go on after damage at `from - 1`: an intact chunk, an
/// attachment with a matching CRC, a metadata record whose lengths add up, or (when the summary
/// is intact) the Data End record.
fn resync(buf: &[u8], from: usize, limit: usize, data_end_at: Option<usize>) -> Option<usize> {
    use mcap::records::op;
    (from..limit.saturating_sub(8)).find(|&p| match buf[p] {
        op::CHUNK => is_sync_chunk(buf, p, limit),
        op::ATTACHMENT => is_sync_attachment(buf, p, limit),
        op::METADATA => is_sync_metadata(buf, p, limit),
        op::DATA_END => Some(p) == data_end_at,
        _ => false,
    })
}

/// The first intact chunk record that starts inside `start..end` (the body of another record).
fn hidden_chunk(buf: &[u8], start: usize, end: usize, limit: usize) -> Option<usize> {
    (start..end).find(|&p| buf[p] == mcap::records::op::CHUNK && is_sync_chunk(buf, p, limit))
}

/// Messages listed by the run of Message Index records starting at `pos`, and where the run ends.
fn index_run(buf: &[u8], mut pos: usize, limit: usize) -> (u64, usize) {
    let mut n = 0u64;
    while let Ok((op, start, end)) = frame(buf, pos, limit) {
        if op != mcap::records::op::MESSAGE_INDEX || !exact(op, &buf[start..end]) {
            break;
        }
        n += (end - start - 6) as u64 / 16;
        pos = end;
    }
    (n, pos)
}

/// Walk a (possibly damaged or cut) MCAP file: every intact chunk wherever it is, the other
/// top-level records that parse, what was skipped, and the checks of the data-section and summary
/// CRCs. After an unreadable record the walk resynchronises on the next intact chunk (see
/// [`resync`]); with an intact summary, chunks, metadata and attachments listed in its indexes are
/// also read at their offsets. Never panics and never allocates from an unchecked length.
pub fn map_file(buf: &[u8]) -> FileMap {
    use mcap::records::op;
    let (complete, summary, summary_problem) = read_summary(buf);
    let limit = summary.as_ref().map_or(buf.len(), |s| s.start);
    let data_end_at = summary.as_ref().and_then(|s| s.start.checked_sub(13));
    let mut m = FileMap {
        records: Vec::new(),
        chunks: Vec::new(),
        skipped: Vec::new(),
        data_end: None,
        data_crc_ok: None,
        summary: None,
        summary_problem,
        complete,
        bytes_used: MAGIC.len().min(buf.len()),
        stopped_because: None,
    };
    let mut pos = MAGIC.len();
    while pos < limit {
        let bad: String = match frame(buf, pos, limit) {
            Err(e) => e,
            Ok((opc, start, end)) => {
                let body = &buf[start..end];
                match opc {
                    op::CHUNK => match chunk_at(buf, pos, limit) {
                        Ok((g, end)) => {
                            push_good(&mut m.chunks, pos, end, g);
                            m.bytes_used = end;
                            pos = end;
                            continue;
                        }
                        Err(b) => {
                            m.chunks.push(bad_slot(pos, b.header.as_ref(), Some(end), &b.reason));
                            format!("damaged chunk at byte {pos}: {}", b.reason)
                        }
                    },
                    op::DATA_END if body.len() == 4 => {
                        let crc = u32::from_le_bytes(body.try_into().expect("4 bytes"));
                        m.data_end = Some((pos, crc));
                        if crc != 0 {
                            m.data_crc_ok = Some(crc32fast::hash(&buf[..pos]) == crc);
                        }
                        m.bytes_used = end;
                        break;
                    }
                    // Records without a CRC of their own are accepted only if no intact chunk
                    // starts inside them: a damaged length cannot swallow chunks.
                    _ if opc != op::ATTACHMENT && hidden_chunk(buf, start, end, limit).is_some() => {
                        let p = hidden_chunk(buf, start, end, limit).unwrap_or(end);
                        format!(
                            "record (opcode 0x{opc:02x}) at byte {pos} runs over the intact chunk at byte {p} \
                             (its length is damaged)"
                        )
                    }
                    op::MESSAGE_INDEX if exact(opc, body) => {
                        m.bytes_used = end;
                        pos = end;
                        continue;
                    }
                    op::HEADER | op::SCHEMA | op::CHANNEL | op::MESSAGE | op::METADATA | op::ATTACHMENT
                        if (opc != op::HEADER || pos == MAGIC.len()) && exact(opc, body) =>
                    {
                        match parse_checked(opc, body) {
                            Ok(r) => {
                                m.records.push((pos, r.into_owned()));
                                m.bytes_used = end;
                                pos = end;
                                continue;
                            }
                            Err(e) => format!("damaged record at byte {pos}: {e}"),
                        }
                    }
                    o if o >= 0x80 => {
                        // Private records are skipped by their length.
                        m.bytes_used = end;
                        pos = end;
                        continue;
                    }
                    o => format!("unexpected or malformed record (opcode 0x{o:02x}) at byte {pos}"),
                }
            }
        };
        if buf.get(pos) == Some(&op::CHUNK) && m.chunks.last().is_none_or(|c| c.offset != pos) {
            // A chunk whose length runs past the end: cut, or its length field is damaged (`pos`
            // is always a record boundary, so the opcode says it is a chunk).
            let h = chunk_at(buf, pos, limit).err().and_then(|b| b.header);
            m.chunks.push(bad_slot(pos, h.as_ref(), None, &bad));
        }
        let next = resync(buf, pos + 1, limit, data_end_at);
        let skip_end = next.unwrap_or(limit);
        // The damaged chunk itself is reported as a chunk; only bytes beyond it count as skipped.
        // A damaged chunk whose end is unknown (length cut or damaged) is taken to reach the next
        // point where reading resumes.
        let covered = m.chunks.last().filter(|c| c.offset == pos).map_or(pos, |c| c.end.unwrap_or(skip_end));
        let covered = covered.min(skip_end);
        let from = if covered > pos { skip_past_indexes(buf, covered, skip_end) } else { pos };
        if from < skip_end {
            m.skipped.push(Skipped { start: from, end: skip_end, reason: bad.clone() });
        }
        if m.stopped_because.is_none() {
            m.stopped_because = Some(bad);
        }
        match next {
            Some(p) => pos = p,
            None => break,
        }
    }
    if m.data_end.is_none() && m.stopped_because.is_none() {
        m.stopped_because = Some("end of data before the Data End record".into());
    }
    if let Some(s) = &summary {
        add_from_summary(buf, s, limit, &mut m);
        // With an intact summary, a damaged "chunk" that its chunk index does not list was some
        // other record whose opcode changed (a message index 0x07 with its low bit flipped).
        let listed: Vec<u64> = s.chunk_indexes.iter().map(|c| c.chunk_start_offset).collect();
        let (real, phantom): (Vec<ChunkSlot>, Vec<ChunkSlot>) = std::mem::take(&mut m.chunks)
            .into_iter()
            .partition(|c| c.content.is_ok() || listed.contains(&(c.offset as u64)));
        m.chunks = real;
        for c in phantom {
            let end = c.end.unwrap_or(c.offset + 9).min(limit);
            let reason =
                format!("not a chunk of the summary's index: {}", c.content.err().unwrap_or_default());
            m.skipped.push(Skipped { start: c.offset, end, reason });
        }
        m.skipped.sort_by_key(|k| k.start);
    }
    m.chunks.sort_by_key(|c| c.offset);
    m.records.sort_by_key(|r| r.0);
    // A damaged chunk's message count comes from the message index records after it, trusted only
    // if their run ends where reading resumed and (with an intact summary) has the length its
    // chunk index gives.
    let mut starts: Vec<usize> = m.chunks.iter().filter(|c| c.content.is_ok()).map(|c| c.offset).collect();
    starts.extend(m.records.iter().map(|r| r.0));
    starts.extend(m.data_end.map(|d| d.0));
    starts.push(limit);
    for c in m.chunks.iter_mut().filter(|c| c.content.is_err()) {
        let Some(end) = c.end else { continue };
        let (n, stop) = index_run(buf, end, limit);
        let len_ok = summary.as_ref().is_none_or(|s| {
            s.chunk_indexes
                .iter()
                .find(|ci| ci.chunk_start_offset == c.offset as u64)
                .is_none_or(|ci| ci.message_index_length == (stop - end) as u64)
        });
        c.messages = (len_ok && starts.contains(&stop)).then_some(n);
    }
    if complete && m.data_end.is_some() && m.summary_problem.is_none() && summary.is_some() {
        m.bytes_used = buf.len();
    }
    m.summary = summary;
    m
}

/// Past the Message Index records that follow a chunk.
fn skip_past_indexes(buf: &[u8], mut pos: usize, limit: usize) -> usize {
    while let Ok((op, start, end)) = frame(buf, pos, limit) {
        if op != mcap::records::op::MESSAGE_INDEX || !exact(op, &buf[start..end]) {
            break;
        }
        pos = end;
    }
    pos
}

fn push_good(chunks: &mut Vec<ChunkSlot>, offset: usize, end: usize, g: GoodChunk<'static>) {
    let header_times_wrong =
        g.log_times.is_some_and(|(a, b)| (a, b) != (g.header.message_start_time, g.header.message_end_time));
    chunks.push(ChunkSlot {
        offset,
        end: Some(end),
        // A chunk without messages (schemas and channels only) has the header's times.
        log_times: g.log_times.or(Some((g.header.message_start_time, g.header.message_end_time))),
        messages: Some(g.messages),
        content: Ok(g.records),
        header_times_wrong,
    });
}

fn bad_slot(offset: usize, header: Option<&ChunkHeader>, end: Option<usize>, reason: &str) -> ChunkSlot {
    ChunkSlot {
        offset,
        end,
        log_times: header.map(|h| (h.message_start_time, h.message_end_time)),
        messages: None,
        content: Err(reason.to_string()),
        header_times_wrong: false,
    }
}

/// Chunks, metadata and attachments listed in an intact summary that the walk did not reach.
fn add_from_summary(buf: &[u8], s: &SummaryInfo, limit: usize, m: &mut FileMap) {
    use mcap::records::op;
    for ci in &s.chunk_indexes {
        let Ok(off) = usize::try_from(ci.chunk_start_offset) else { continue };
        let end = usize::try_from(ci.chunk_start_offset.saturating_add(ci.chunk_length)).ok();
        if let Some(c) = m.chunks.iter_mut().find(|c| c.offset == off) {
            if c.content.is_err() {
                c.log_times = Some((ci.message_start_time, ci.message_end_time));
            }
            continue;
        }
        if off < MAGIC.len() || off >= limit {
            continue;
        }
        let slot = match chunk_at(buf, off, limit) {
            Ok((g, e)) => {
                let mut v = Vec::new();
                push_good(&mut v, off, e, g);
                v.pop()
            }
            Err(b) => {
                let mut c = bad_slot(off, None, end.filter(|&e| e <= limit), &b.reason);
                c.log_times = Some((ci.message_start_time, ci.message_end_time));
                Some(c)
            }
        };
        if let Some(c) = slot {
            m.chunks.push(c);
        }
    }
    let mut extra = |off: u64, len: u64, want: u8| {
        let (Ok(off), Ok(len)) = (usize::try_from(off), usize::try_from(len)) else { return };
        if m.records.iter().any(|r| r.0 == off) || off < MAGIC.len() {
            return;
        }
        let Ok((opc, start, end)) = frame(buf, off, limit) else { return };
        if opc != want || end - off != len || !exact(opc, &buf[start..end]) {
            return;
        }
        if let Ok(r) = parse_checked(opc, &buf[start..end]) {
            m.records.push((off, r.into_owned()));
        }
    };
    for mi in &s.metadata_indexes {
        extra(mi.offset, mi.length, op::METADATA);
    }
    for ai in &s.attachment_indexes {
        extra(ai.offset, ai.length, op::ATTACHMENT);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corrupt_length_prefixes_are_refused_before_parsing() {
        use mcap::records::op;
        // Metadata: name "ab", then a map whose first key claims 4 GiB (a fuzzer find).
        let mut body = vec![2, 0, 0, 0, b'a', b'b'];
        body.extend_from_slice(&12u32.to_le_bytes());
        body.extend_from_slice(&0xFFFF_FF00u32.to_le_bytes());
        body.extend_from_slice(b"kkkkvvvv");
        assert!(!plausible(op::METADATA, &body));
        assert!(
            parse_checked(op::METADATA, &body).unwrap_err().starts_with("malformed record (opcode 0x0c)")
        );
        // The same record with honest lengths parses.
        let mut good = vec![2, 0, 0, 0, b'a', b'b'];
        good.extend_from_slice(&10u32.to_le_bytes());
        good.extend_from_slice(&1u32.to_le_bytes());
        good.push(b'k');
        good.extend_from_slice(&1u32.to_le_bytes());
        good.push(b'v');
        assert!(plausible(op::METADATA, &good));
        let Ok(Record::Metadata(m)) = parse_checked(op::METADATA, &good) else { panic!("metadata") };
        assert_eq!((m.name.as_str(), m.metadata["k"].as_str()), ("ab", "v"));
        // A chunk whose records length runs past the body.
        let mut chunk = vec![0u8; 28];
        chunk.extend_from_slice(&0u32.to_le_bytes());
        chunk.extend_from_slice(&u64::MAX.to_le_bytes());
        assert!(!plausible(op::CHUNK, &chunk));
    }
}
