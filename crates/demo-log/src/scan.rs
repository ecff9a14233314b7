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
    use mcap::records::op;
    let mut c = Check { b: body, pos: 0 };
    let ok = match op {
        op::HEADER => c.str().and_then(|_| c.str()),
        op::FOOTER => c.take(20),
        op::SCHEMA => c.take(2).and_then(|_| c.str()).and_then(|_| c.str()).and_then(|_| c.str()),
        op::CHANNEL => c.take(4).and_then(|_| c.str()).and_then(|_| c.str()).and_then(|_| c.string_map()),
        op::MESSAGE => c.take(22),
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
        _ => None,
    };
    ok.is_some()
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
