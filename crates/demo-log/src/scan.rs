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

/// The records inside a decoded chunk, all or nothing.
pub fn chunk_records(decoded: &[u8]) -> Result<Vec<Record<'_>>, String> {
    let mut v = Vec::new();
    for r in mcap::read::LinearReader::sans_magic(decoded) {
        v.push(r.map_err(|e| format!("record inside chunk: {e}"))?);
    }
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
