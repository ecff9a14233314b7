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
