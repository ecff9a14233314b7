//! Verification and salvage of damaged demos against a ground truth computed independently from
//! the undamaged file's chunk index (read with the `mcap` crate's own summary reader).

mod common;

use common::*;
use demo_log::*;
use std::collections::BTreeMap;
use std::path::Path;

fn opts_small() -> WriterOptions {
    WriterOptions { chunk_size: 4096, flush_every_steps: 5, compression_level: 0 }
}

/// One chunk of the undamaged file.
struct ChunkTruth {
    start: usize,
    end: usize,
    t0: u64,
    t1: u64,
    /// (topic, log time, data) of its messages, in order.
    msgs: Vec<(String, u64, Vec<u8>)>,
}

struct Truth {
    buf: Vec<u8>,
    chunks: Vec<ChunkTruth>,
    summary_start: usize,
    total: usize,
    /// The episode's rows, by step number.
    episode: Episode,
}

fn truth(path: &Path) -> Truth {
    let buf = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().unwrap();
    let mut idx = summary.chunk_indexes.clone();
    idx.sort_by_key(|c| c.chunk_start_offset);
    let chunks: Vec<ChunkTruth> = idx
        .iter()
        .map(|ci| ChunkTruth {
            start: ci.chunk_start_offset as usize,
            end: (ci.chunk_start_offset + ci.chunk_length) as usize,
            t0: ci.message_start_time,
            t1: ci.message_end_time,
            msgs: summary
                .stream_chunk(&buf, ci)
                .unwrap()
                .map(|m| {
                    let m = m.unwrap();
                    (m.channel.topic.clone(), m.log_time, m.data.into_owned())
                })
                .collect(),
        })
        .collect();
    let total = chunks.iter().map(|c| c.msgs.len()).sum();
    assert_eq!(total, mcap::MessageStream::new(&buf).unwrap().count());
    let footer_pos = buf.len() - 8 - 29;
    let summary_start = u64::from_le_bytes(buf[footer_pos + 9..footer_pos + 17].try_into().unwrap()) as usize;
    Truth { episode: read_demo(path).unwrap(), buf, chunks, summary_start, total }
}

/// Whether chunk `c` of the original survives in `b` (the original cut and/or with bytes
/// changed): wholly before the cut, and either no byte changed except in the two log-time fields
/// of its header (bytes 9..25 of the record, which the chunk CRC does not cover and salvage does
/// not need), or the changes are all in the compressed records and zstd still decompresses them
/// to exactly the original records (a flipped bit in an unused part of a zstd block).
fn intact(c: &ChunkTruth, orig: &[u8], b: &[u8]) -> bool {
    if c.end > b.len() {
        return false;
    }
    let changed: Vec<usize> =
        (c.start..c.end).filter(|&i| b[i] != orig[i] && !(c.start + 9..c.start + 25).contains(&i)).collect();
    if changed.is_empty() {
        return true;
    }
    // op 1, length 8, times 16, uncompressed size 8, crc 4, "zstd" 4 + 4, records length 8.
    let data = c.start + 53;
    assert_eq!(&orig[c.start + 41..c.start + 45], b"zstd");
    if changed[0] < data {
        return false;
    }
    let n = u64::from_le_bytes(orig[c.start + 25..c.start + 33].try_into().unwrap()) as usize;
    let want = zstd::bulk::decompress(&orig[data..c.end], n).unwrap();
    zstd::bulk::decompress(&b[data..c.end], n).is_ok_and(|got| got == want)
}

fn step_of(data: &[u8]) -> u64 {
    serde_json::from_slice::<serde_json::Value>(data).unwrap()["step"].as_u64().unwrap()
}

/// Check salvage, salvage_to + read_demo and verify on the damaged bytes `b` against the truth.
fn check(t: &Truth, b: &[u8], dir: &Path, tag: &str) -> Result<(), String> {
    let orig = &t.buf;
    let ok_chunks: Vec<&ChunkTruth> = t.chunks.iter().filter(|c| intact(c, orig, b)).collect();
    let expected: Vec<(String, u64, Vec<u8>)> =
        ok_chunks.iter().flat_map(|c| c.msgs.iter().cloned()).collect();
    let name = Path::new("damaged.mcap");
    let s = salvage_bytes(b, name).map_err(|e| e.to_string())?;
    let got: Vec<(String, u64, Vec<u8>)> =
        s.messages.iter().map(|m| (m.topic.clone(), m.log_time, m.data.clone())).collect();
    if got != expected {
        let changes: Vec<String> = (0..b.len().min(orig.len()))
            .filter(|&i| b[i] != orig[i])
            .map(|i| match t.chunks.iter().position(|c| (c.start..c.end).contains(&i)) {
                Some(k) => format!("byte {i} = chunk {k} + {}", i - t.chunks[k].start),
                None => format!("byte {i} outside chunks"),
            })
            .collect();
        return Err(format!(
            "{tag}: recovered {} messages, the {} intact chunks of {} hold {}; changes {changes:?}, length {} of {}",
            got.len(),
            ok_chunks.len(),
            t.chunks.len(),
            expected.len(),
            b.len(),
            orig.len()
        ));
    }
    if s.report.chunks_ok as usize != ok_chunks.len() {
        return Err(format!("{tag}: chunks_ok {} != {}", s.report.chunks_ok, ok_chunks.len()));
    }
    // The salvaged file loads, with exactly the recovered steps.
    let inp = dir.join(format!("{tag}.in.mcap"));
    let out = dir.join(format!("{tag}.out.mcap"));
    std::fs::write(&inp, b).unwrap();
    if let Err(e) = salvage_to(&inp, &out) {
        // Refused only when nothing recognisable survives (e.g. a cut inside the MCAP header),
        // never when an intact chunk's messages exist.
        let e = e.to_string();
        return if expected.is_empty() && e.contains("nothing recognisable as a demo survives") {
            Ok(())
        } else {
            Err(format!("{tag}: salvage_to: {e}"))
        };
    }
    let ep = read_demo(&out).map_err(|e| format!("{tag}: salvaged file does not load: {e}"))?;
    let steps: Vec<u64> = expected.iter().filter(|m| m.0 == TOPIC_STEP).map(|m| step_of(&m.2)).collect();
    if ep.len() != steps.len() {
        return Err(format!("{tag}: loaded {} steps, recovered {}", ep.len(), steps.len()));
    }
    let (od, whole) = (t.episode.obs_dim, &t.episode);
    for (row, &st) in steps.iter().enumerate() {
        let st = st as usize;
        if ep.obs[row * od..(row + 1) * od] != whole.obs[st * od..(st + 1) * od] || ep.t[row] != whole.t[st] {
            return Err(format!("{tag}: row {row} is not step {st}"));
        }
        // The row before a gap is marked truncated; the others keep their flags.
        let before_gap = row + 1 < steps.len() && steps[row + 1] as usize != st + 1;
        if ep.truncated[row] != (whole.truncated[st] || before_gap) {
            return Err(format!("{tag}: truncated flag of row {row} (step {st})"));
        }
    }
    let _ = std::fs::remove_file(&inp);
    let _ = std::fs::remove_file(&out);
    // Verification: any change or cut is a problem; with the summary intact every damaged chunk
    // is named, and only those.
    let v = verify_bytes(b, name).map_err(|e| e.to_string())?;
    let changed = b.len() != orig.len() || b != &orig[..];
    if v.is_ok() == changed {
        return Err(format!("{tag}: verify ok={} for a file changed={changed}: {:?}", v.is_ok(), v.problems));
    }
    let summary_intact = b.len() == orig.len() && b[t.summary_start..] == orig[t.summary_start..];
    if summary_intact {
        let named: Vec<u64> = v.chunks.iter().filter(|c| !c.recoverable).map(|c| c.offset).collect();
        let lost: Vec<u64> =
            t.chunks.iter().filter(|c| !intact(c, orig, b)).map(|c| c.start as u64).collect();
        if named != lost {
            return Err(format!("{tag}: verify names chunks at {named:?}, damaged are {lost:?}"));
        }
        let n_lost: u64 = t.chunks.iter().filter(|c| !intact(c, orig, b)).map(|c| c.msgs.len() as u64).sum();
        if v.messages_ok + v.messages_lost.unwrap_or(n_lost) != t.total as u64 {
            return Err(format!(
                "{tag}: verify counts {} + {:?} of {}",
                v.messages_ok, v.messages_lost, t.total
            ));
        }
    }
    Ok(())
}

fn base(name: &str, n: u64) -> (std::path::PathBuf, Truth) {
    let d = tmpdir(name);
    let p = d.join("a.mcap");
    write_demo(&p, 0, n, 16, 7, opts_small());
    let t = truth(&p);
    (d, t)
}

#[test]
fn healthy_file_verifies() {
    let (d, t) = base("verify-ok", 60);
    let v = verify(d.join("a.mcap")).unwrap();
    assert!(v.is_ok(), "{:?}", v.problems);
    assert!(v.complete);
    assert_eq!(v.data_crc_ok, Some(true));
    assert_eq!(v.chunks.len(), t.chunks.len());
    assert!(t.chunks.len() >= 10, "the tests need many chunks, got {}", t.chunks.len());
    assert_eq!((v.messages_ok, v.messages_lost), (t.total as u64, Some(0)));
    for (c, ct) in v.chunks.iter().zip(&t.chunks) {
        assert_eq!(
            (c.offset, c.length, c.messages),
            (ct.start as u64, Some((ct.end - ct.start) as u64), Some(ct.msgs.len() as u64))
        );
        assert_eq!(c.log_times, Some((ct.t0, ct.t1)));
    }
}

#[test]
fn one_flipped_bit_in_any_chunk_loses_only_that_chunk_and_is_named() {
    let (d, t) = base("flip-each", 60);
    for (k, c) in t.chunks.iter().enumerate() {
        let mut b = t.buf.clone();
        b[(c.start + c.end) / 2] ^= 0x10;
        check(&t, &b, &d, &format!("flip{k}")).unwrap();
        let v = verify_bytes(&b, Path::new("x.mcap")).unwrap();
        let bad: Vec<&ChunkCheck> = v.damaged_chunks().collect();
        assert_eq!(bad.len(), 1, "chunk {k}: {:?}", v.problems);
        assert_eq!((bad[0].index, bad[0].offset), (k as u64, c.start as u64));
        assert_eq!(bad[0].messages, Some(c.msgs.len() as u64));
        assert_eq!(bad[0].log_times, Some((c.t0, c.t1)));
        assert!(v.problems[0].starts_with(&format!("chunk {k} at byte {}: ", c.start)), "{}", v.problems[0]);
        // Salvage: every other chunk's messages.
        let s = salvage_bytes(&b, Path::new("x.mcap")).unwrap();
        assert_eq!(s.messages.len(), t.total - c.msgs.len());
        assert_eq!((s.report.chunks_ok as usize, s.report.chunks_lost), (t.chunks.len() - 1, 1));
    }
}

#[test]
fn lost_middle_chunk_gives_a_loadable_file_with_the_gap_declared() {
    let (d, t) = base("gap", 60);
    let k = t.chunks.len() / 2;
    let c = &t.chunks[k];
    let mut b = t.buf.clone();
    b[(c.start + c.end) / 2] ^= 1;
    let inp = d.join("in.mcap");
    std::fs::write(&inp, &b).unwrap();
    let e = read_demo(&inp).unwrap_err().to_string();
    assert!(e.contains("salvage"), "{e}");
    let out = d.join("out.mcap");
    let r = salvage_to(&inp, &out).unwrap();
    let lost: Vec<u64> = c.msgs.iter().filter(|m| m.0 == TOPIC_STEP).map(|m| step_of(&m.2)).collect();
    assert!(!lost.is_empty(), "the test wants a chunk with steps");
    let gap = (lost[0], lost[lost.len() - 1] + 1);
    assert_eq!(r.step_gaps, vec![gap]);
    let ep = read_demo(&out).unwrap();
    assert_eq!(ep.len() as u64, 60 - (gap.1 - gap.0));
    assert_eq!(ep.meta["salvage.step_gaps"], format!("{}..{}", gap.0, gap.1));
    assert_eq!(ep.meta["task"], "suction");
    assert_eq!(ep.meta["salvage.lost_chunks"], format!("{k}@{}:{}..{}ns", c.start, c.t0, c.t1));
    assert_eq!(ep.truncated.iter().filter(|&&x| x).count(), 1);
    assert!(ep.truncated[gap.0 as usize - 1]);
    // Salvaging the salvaged file keeps the gap and still loads.
    let again = d.join("again.mcap");
    let r2 = salvage_to(&out, &again).unwrap();
    assert_eq!(r2.step_gaps, vec![gap]);
    assert_eq!(read_demo(&again).unwrap().obs, ep.obs);
    // And the salvaged file is itself healthy.
    assert!(verify(&out).unwrap().is_ok());
}

/// A file written with the `mcap` crate from the demo's records, steps `skip` left out, and an
/// optional `salvage` record declaring `gaps`.
fn without_steps(t: &Truth, skip: std::ops::Range<u64>, gaps: Option<&str>, path: &Path) {
    let summary = mcap::Summary::read(&t.buf).unwrap().unwrap();
    let mut w = mcap::WriteOptions::new()
        .create(std::io::BufWriter::new(std::fs::File::create(path).unwrap()))
        .unwrap();
    for s in summary.schemas.values() {
        w.add_schema_with_id(s.id, &s.name, &s.encoding, &s.data).unwrap();
    }
    for c in summary.channels.values() {
        let sid = c.schema.as_ref().map_or(0, |s| s.id);
        w.add_channel_with_id(c.id, sid, &c.topic, &c.message_encoding, &c.metadata).unwrap();
    }
    if let Some(g) = gaps {
        let md = BTreeMap::from([("step_gaps".to_string(), g.to_string())]);
        w.write_metadata(&mcap::records::Metadata { name: "salvage".into(), metadata: md }).unwrap();
    }
    for m in mcap::MessageStream::new(&t.buf).unwrap() {
        let m = m.unwrap();
        if m.channel.topic == TOPIC_STEP && skip.contains(&step_of(&m.data)) {
            continue;
        }
        let h = mcap::records::MessageHeader {
            channel_id: m.channel.id,
            sequence: m.sequence,
            log_time: m.log_time,
            publish_time: m.publish_time,
        };
        w.write_to_known_channel(&h, &m.data).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn the_reader_accepts_only_declared_gaps() {
    let (d, t) = base("declared", 30);
    let p = d.join("g.mcap");
    without_steps(&t, 5..10, None, &p);
    let e = read_demo(&p).unwrap_err().to_string();
    assert!(e.ends_with("step 10 found where step 5 was expected"), "{e}");
    without_steps(&t, 5..10, Some("5..9"), &p);
    let e = read_demo(&p).unwrap_err().to_string();
    assert!(e.contains("does not declare steps 5..10 lost"), "{e}");
    without_steps(&t, 5..10, Some("bogus"), &p);
    assert!(read_demo(&p).is_err());
    without_steps(&t, 5..10, Some("5..10"), &p);
    let ep = read_demo(&p).unwrap();
    assert_eq!(ep.len(), 25);
    assert_eq!(ep.obs[5 * 16..6 * 16], t.episode.obs[10 * 16..11 * 16]);
    assert!(ep.truncated[4] && !ep.truncated[3] && !ep.truncated[5]);
    // A leading gap marks nothing.
    without_steps(&t, 0..3, Some("0..3"), &p);
    let ep = read_demo(&p).unwrap();
    assert_eq!((ep.len(), ep.truncated.iter().filter(|&&x| x).count()), (27, 0));
}

#[test]
fn without_chunk_0_and_summary_the_writer_layout_is_used_and_matches_the_writer() {
    let (d, t) = base("layout", 60);
    let c0 = &t.chunks[0];
    let mut b = t.buf.clone();
    b[(c0.start + c0.end) / 2] ^= 4;
    let mid = &t.chunks[t.chunks.len() / 2];
    b.truncate(mid.start + 100);
    check(&t, &b, &d, "layout").unwrap();
    let inp = d.join("in.mcap");
    std::fs::write(&inp, &b).unwrap();
    let out = d.join("out.mcap");
    let r = salvage_to(&inp, &out).unwrap();
    assert!(r.layout_assumed);
    let a = mcap::Summary::read(&t.buf).unwrap().unwrap();
    let s = std::fs::read(&out).unwrap();
    let z = mcap::Summary::read(&s).unwrap().unwrap();
    let sch = |x: &mcap::Summary| {
        x.schemas
            .values()
            .map(|s| (s.id, s.name.clone(), s.encoding.clone(), s.data.to_vec()))
            .collect::<Vec<_>>()
    };
    let chans = |x: &mcap::Summary| {
        x.channels
            .values()
            .map(|c| {
                (
                    c.id,
                    c.topic.clone(),
                    c.schema.as_ref().map(|s| s.id),
                    c.message_encoding.clone(),
                    c.metadata.clone(),
                )
            })
            .collect::<Vec<_>>()
    };
    let (mut s1, mut s2, mut c1, mut c2) = (sch(&z), sch(&a), chans(&z), chans(&a));
    s1.sort();
    s2.sort();
    c1.sort();
    c2.sort();
    assert!(s1 == s2, "schemas differ");
    assert!(c1 == c2, "channels differ");
    // Without the Header and the metadata records the step messages themselves identify a demo.
    let mut b2 = b.clone();
    for x in &mut b2[8..c0.start] {
        *x = 0;
    }
    let s2 = salvage_bytes(&b2, Path::new("x.mcap")).unwrap();
    assert!(s2.report.layout_assumed);
    assert_eq!(s2.messages.len(), salvage_bytes(&b, Path::new("x.mcap")).unwrap().messages.len());
}

#[test]
fn a_flipped_chunk_length_or_opcode_resynchronises() {
    let (d, t) = base("resync", 60);
    let c = &t.chunks[3];
    // Chunk record: opcode, length (8), start and end times (8 + 8), uncompressed size (8), CRC
    // (4), compression ("zstd" with its u32 length), records length (8), records.
    let fields = [
        ("opcode", c.start),
        ("record length", c.start + 3),
        ("start time", c.start + 9),
        ("end time", c.start + 17),
        ("uncompressed size", c.start + 25),
        ("crc", c.start + 33),
        ("compression", c.start + 42),
        ("records length", c.start + 45),
    ];
    for (what, at) in fields {
        let mut b = t.buf.clone();
        b[at] ^= 0x41;
        check(&t, &b, &d, what).unwrap_or_else(|e| panic!("{what}: {e}"));
        let v = verify_bytes(&b, Path::new("x.mcap")).unwrap();
        let named: Vec<u64> = v.damaged_chunks().map(|c| c.index).collect();
        assert_eq!(named, [3], "{what}: {:?}", v.problems);
    }
}

/// Found by the `salvage_damage` fuzz target: a flipped bit in the MCAP Header's length made the
/// Header (which has no CRC) swallow the chunks after it.
#[test]
fn a_record_whose_length_grew_swallows_no_chunk() {
    let (d, t) = base("swallow", 60);
    for (k, x) in [(10usize, 0x3bu8), (10, 0x01), (11, 0x01)] {
        let mut b = t.buf.clone();
        b[k] ^= x;
        // Without the summary (cut in the last chunk) only the walk finds the chunks.
        let last = t.chunks.last().unwrap();
        b.truncate(last.start + 20);
        check(&t, &b, &d, &format!("header{k}x{x}")).unwrap();
        let v = verify_bytes(&b, Path::new("x.mcap")).unwrap();
        // Only the cut last chunk is damaged; the header is reported as unreadable bytes.
        let bad: Vec<u64> = v.damaged_chunks().map(|c| c.offset).collect();
        assert_eq!(bad, [last.start as u64], "{:?}", v.problems);
        assert!(v.problems.iter().any(|p| p.starts_with("bytes 8..")), "{:?}", v.problems);
    }
    // The same for the `episode_start` metadata record's length.
    let md = t.buf[..t.chunks[0].start].iter().position(|&x| x == 0x0c).unwrap();
    let mut b = t.buf.clone();
    b[md + 2] ^= 0x40;
    b.truncate(t.summary_start - 20);
    check(&t, &b, &d, "metadata-length").unwrap();
}

#[test]
fn metadata_damage_is_found_by_the_data_crc() {
    let (_d, t) = base("md", 30);
    let mut b = t.buf.clone();
    // A letter of the task name in the `episode_start` record (before the first chunk).
    let pos = t.buf[..t.chunks[0].start].windows(7).position(|w| w == b"suction").unwrap() + 2;
    b[pos] ^= 0x20;
    let v = verify_bytes(&b, Path::new("x.mcap")).unwrap();
    assert!(!v.is_ok());
    assert_eq!(v.data_crc_ok, Some(false));
    assert!(v.problems.iter().any(|p| p.starts_with("data section CRC mismatch")), "{:?}", v.problems);
    assert_eq!(v.damaged_chunks().count(), 0);
}

/// Found by the property test: one flipped bit in the `episode` record's `terminated` ("true" →
/// "urue"). Metadata has no CRC, so salvage carried the record over and the salvaged file did not
/// load; the record is now left out and named in the report.
#[test]
fn a_damaged_episode_record_is_dropped_and_named() {
    let (d, t) = base("md-drop", 30);
    let at = t.buf.windows(15).rposition(|w| w == b"terminated\x04\0\0\0t").expect("terminated") + 14;
    let mut b = t.buf.clone();
    b[at] ^= 0x01;
    check(&t, &b, &d, "md-drop").unwrap();
    let s = salvage_bytes(&b, Path::new("x.mcap")).unwrap();
    assert_eq!(s.report.metadata_dropped, ["episode: terminated is \"urue\", not true or false"]);
    assert!(s.metadata.iter().all(|(n, _)| n != "episode"));
    assert!(s.metadata.iter().any(|(n, _)| n == "episode_start"));
}

mod properties {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    fn t() -> &'static (std::path::PathBuf, Truth) {
        static T: OnceLock<(std::path::PathBuf, Truth)> = OnceLock::new();
        T.get_or_init(|| base("prop", 60))
    }

    fn cases() -> u32 {
        std::env::var("SALVAGE_PROPTEST_CASES").ok().and_then(|s| s.parse().ok()).unwrap_or(256)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(cases()))]

        /// Random bit flips and/or a cut: salvage recovers exactly the messages of the intact
        /// chunks, the salvaged file loads with exactly those steps, and verify names the damage.
        #[test]
        fn prop_salvage_recovers_exactly_the_intact_chunks(
            flips in prop::collection::vec((any::<prop::sample::Index>(), 0u8..8), 0..6),
            cut in prop::option::of(any::<prop::sample::Index>()),
            in_chunks in any::<bool>(),
        ) {
            let (d, t) = t();
            let mut b = t.buf.clone();
            for (i, bit) in &flips {
                // Half the cases aim the flips at the chunks' bytes, the others anywhere.
                let k = if in_chunks {
                    let c = &t.chunks[i.index(t.chunks.len())];
                    c.start + i.index(c.end - c.start)
                } else {
                    8 + i.index(b.len() - 8)
                };
                b[k] ^= 1 << bit;
            }
            if let Some(c) = cut {
                b.truncate(8 + c.index(b.len() - 8 + 1));
            }
            if let Err(e) = check(t, &b, d, "prop") {
                return Err(TestCaseError::fail(e));
            }
        }
    }
}
