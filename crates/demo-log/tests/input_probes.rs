//! Regression tests for issue 24 (items 1-8, 16) at the crate's level: the one file reader
//! refuses what is not a regular file, hand-log objects hold each key once, the parse report
//! hashes exactly the bytes parsed, coordinates are bounded, loading checks the data-section CRC
//! and the episode record like `verify`, and salvage reads on past a damaged leading magic.

mod common;

use common::*;
use demo_log::*;
use std::path::Path;

const HEADER: &str = r#"{"format":"mimicrete.handlog","version":1,"layout":"mediapipe","space":"openxr","handedness":"right","units":"m"}"#;

fn frame(t: f64) -> String {
    let j: Vec<String> = (0..21).map(|k| format!("[{}, 1.2, -0.3]", 0.01 * k as f64)).collect();
    format!(r#"{{"t":{t},"tracked":true,"joints":[{}]}}"#, j.join(","))
}

fn strict(text: &str) -> Result<(HandLog, ParseReport), HandLogError> {
    HandLog::parse_str(text, "h.jsonl", ParseMode::Strict)
}

#[test]
fn duplicated_keys_are_refused_at_their_line() {
    let dup_header = HEADER.replace(r#""units":"m""#, r#""units":"m","handedness":"left""#);
    let e = strict(&format!("{dup_header}\n{}\n", frame(0.0))).unwrap_err();
    assert_eq!((e.line, e.reason.starts_with(r#"header: duplicate key "handedness""#)), (1, true), "{e}");
    let dup_t = frame(0.1).replacen(r#"{"t":"#, r#"{"t":5.0,"t":"#, 1);
    let e = strict(&format!("{HEADER}\n{}\n{dup_t}\n", frame(0.0))).unwrap_err();
    assert_eq!(e.line, 3);
    assert!(e.reason.starts_with(r#"duplicate key "t""#), "{e}");
    // Nested objects too, and the last line without a newline is not called "truncated".
    let nested = HEADER.replace(r#""units":"m""#, r#""units":"m","extra":{"a":1,"a":2}"#);
    assert!(
        strict(&format!("{nested}\n{}", frame(0.0))).unwrap_err().reason.contains(r#"duplicate key "a""#)
    );
    let e = strict(&format!(
        "{HEADER}\n{}",
        frame(0.0).replace(r#""tracked":true"#, r#""tracked":true,"tracked":false"#)
    ))
    .unwrap_err();
    assert!(e.reason.starts_with(r#"duplicate key "tracked""#), "{e}");
    // Lenient mode skips such a frame like any bad one.
    let (log, rep) =
        HandLog::parse_str(&format!("{HEADER}\n{dup_t}\n{}\n", frame(0.2)), "h", ParseMode::Lenient).unwrap();
    assert_eq!((log.frames.len(), rep.invalid_skipped), (1, 1));
    // Held: equal keys in different objects.
    assert_eq!(strict(&format!("{HEADER}\n{}\n{}\n", frame(0.0), frame(0.1))).unwrap().0.frames.len(), 2);
}

#[test]
fn coordinates_beyond_ten_kilometres_are_refused_by_parse_and_write() {
    let huge = frame(0.0).replacen("[0, 1.2", "[1e300, 1.2", 1);
    let e = strict(&format!("{HEADER}\n{huge}\n")).unwrap_err();
    assert_eq!(e.line, 2);
    assert!(e.reason.starts_with("joint 0 coordinate x is 1e300 m, out of range"), "{e}");
    let edge = frame(0.0).replacen("[0, 1.2", "[10000, 1.2", 1);
    assert!(strict(&format!("{HEADER}\n{edge}\n")).is_ok());
    let (mut log, _) = strict(&format!("{HEADER}\n{}\n", frame(0.0))).unwrap();
    log.frames[0].joints[3][2] = -2e4;
    assert!(log.to_jsonl().unwrap_err().reason.starts_with("joint 3 coordinate z is -20000 m"));
}

#[test]
fn the_parse_report_hashes_the_bytes_parsed() {
    let d = tmpdir("probe-hash");
    let p = d.join("h.jsonl");
    let text = format!("{HEADER}\n{}\n", frame(0.0));
    std::fs::write(&p, &text).unwrap();
    let (_, rep) = HandLog::from_path(&p, ParseMode::Strict).unwrap();
    assert_eq!(rep.sha256.as_deref(), Some(sha256_hex(text.as_bytes()).as_str()));
    assert_eq!(strict(&text).unwrap().1.sha256, None);
    // The writer records a hash it is given instead of reading the (meanwhile grown) file.
    std::fs::write(&p, format!("{text}{}\n", frame(1.0))).unwrap();
    let mut m = meta(0);
    m.source_handlog = Some(p.clone());
    m.source_handlog_sha256 = rep.sha256.clone();
    let out = d.join("x.mcap");
    DemoWriter::create(&out, &m).unwrap().finish(&EpisodeSummary::default()).unwrap();
    assert_eq!(read_demo(&out).unwrap().meta["source_handlog_sha256"], sha256_hex(text.as_bytes()));
    m.source_handlog_sha256 = Some("not hex".into());
    assert!(DemoWriter::create(d.join("y.mcap"), &m).is_err());
}

#[cfg(unix)]
#[test]
fn readers_refuse_what_is_not_a_regular_file_without_blocking() {
    let d = tmpdir("probe-fifo");
    let fifo = d.join("x.mcap");
    let ok = std::process::Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(ok.success());
    let msg = |r: Result<(), DemoError>| r.unwrap_err().to_string();
    let want = format!("{}: not a regular file (a named pipe)", fifo.display());
    assert_eq!(msg(read_demo(&fifo).map(drop)), want);
    assert_eq!(msg(verify(&fifo).map(drop)), want);
    assert_eq!(msg(salvage(&fifo).map(drop)), want);
    assert_eq!(msg(salvage_to(&fifo, d.join("o.mcap")).map(drop)), want);
    let e = HandLog::from_path(&fifo, ParseMode::Strict).unwrap_err();
    assert_eq!((e.line, e.reason.as_str()), (1, "not a regular file (a named pipe)"));
    assert_eq!(msg(read_input(&d).map(drop)), format!("{}: not a regular file (a directory)", d.display()));
    // A dangling link is listed and refused by name; a link to a demo is read.
    std::os::unix::fs::symlink(d.join("gone.mcap"), d.join("y.mcap")).unwrap();
    assert_eq!(demo_files(&d).unwrap(), vec![fifo.clone(), d.join("y.mcap")]);
    assert!(msg(read_demo(d.join("y.mcap")).map(drop)).contains("y.mcap: dangling symbolic link"));
    std::fs::remove_file(&fifo).unwrap();
    std::fs::remove_file(d.join("y.mcap")).unwrap();
    write_demo(&d.join("real.mcap"), 0, 5, 4, 2, WriterOptions::default());
    std::os::unix::fs::symlink(d.join("real.mcap"), d.join("z.mcap")).unwrap();
    assert_eq!(load_dataset(&d).unwrap().files.len(), 2);
}

fn demo_bytes(name: &str) -> (std::path::PathBuf, Vec<u8>) {
    let d = tmpdir(name);
    let p = d.join("a.mcap");
    write_demo(
        &p,
        0,
        30,
        4,
        2,
        WriterOptions { chunk_size: 4096, flush_every_steps: 5, compression_level: 0 },
    );
    let b = std::fs::read(&p).unwrap();
    (p, b)
}

/// Byte offset of the value of `key` in the last metadata record holding it.
fn value_at(b: &[u8], key: &[u8]) -> usize {
    let i = b.windows(key.len()).rposition(|w| w == key).unwrap();
    i + key.len() + 4
}

#[test]
fn a_flipped_bit_in_the_episode_record_is_refused_by_the_reader_as_by_verify() {
    let (p, good) = demo_bytes("probe-meta");
    assert!(read_demo_bytes(&good, &p).is_ok());
    let mut b = good.clone();
    let at = value_at(&b, b"control_dt");
    assert_eq!(&b[at..at + 4], b"0.04");
    b[at + 3] ^= 1; // 0.04 -> 0.05
    let e = read_demo_bytes(&b, &p).unwrap_err().to_string();
    assert!(e.contains("data section CRC mismatch"), "{e}");
    assert!(!verify_bytes(&b, &p).unwrap().is_ok());
    let mut b = good.clone();
    let at = value_at(&b, b"success");
    b[at + 1] ^= 2; // true -> tpue
    let e = read_demo_bytes(&b, &p).unwrap_err().to_string();
    assert!(e.contains(r#"metadata record "episode": success is "tpue""#), "{e}");
    // Held: salvage still recovers every step of such a file.
    let s = salvage_bytes(&b, &p).unwrap();
    assert_eq!(s.report.chunks_lost, 0);
}

#[test]
fn the_episode_record_is_checked_by_one_function() {
    let mut m = std::collections::BTreeMap::new();
    m.insert("success".to_string(), "true".to_string());
    m.insert("control_dt".to_string(), "0.04".to_string());
    assert!(check_episode_record(&m).is_ok());
    m.insert("success".into(), "tpue".into());
    assert_eq!(check_episode_record(&m).unwrap_err(), r#"success is "tpue", not true or false"#);
    m.insert("success".into(), "false".into());
    m.insert("control_dt".into(), "-0.04".into());
    assert!(check_episode_record(&m).unwrap_err().starts_with("control_dt is"));
    m.insert("control_dt".into(), "0.04".into());
    m.insert("length".into(), "3x".into());
    assert!(check_episode_record(&m).unwrap_err().starts_with("length is"));
}

#[test]
fn salvage_reads_on_past_a_damaged_leading_magic() {
    let (p, good) = demo_bytes("probe-magic");
    let steps = read_demo_bytes(&good, &p).unwrap().len();
    for (byte, bit) in [(3usize, 0x04u8), (0, 0x80), (7, 0x01)] {
        let mut b = good.clone();
        b[byte] ^= bit;
        let s = salvage_bytes(&b, &p).unwrap();
        assert!(s.report.magic_damaged && s.report.chunks_lost == 0);
        let r = verify_bytes(&b, &p).unwrap();
        assert!(r.problems[0].starts_with("the leading magic is damaged"), "{:?}", r.problems);
        let e = read_demo_bytes(&b, &p).unwrap_err().to_string();
        assert!(e.contains("leading magic is damaged") && e.contains("salvage_to"), "{e}");
        let bad = p.with_file_name(format!("bad{byte}.mcap"));
        std::fs::write(&bad, &b).unwrap();
        let fixed = p.with_file_name(format!("fixed{byte}.mcap"));
        salvage_to(&bad, &fixed).unwrap();
        assert_eq!(read_demo(&fixed).unwrap().len(), steps);
    }
    // Held: something that is not MCAP at all is still refused.
    let mut other = b"\x89PNG\r\n\x1a\n".to_vec();
    other.extend_from_slice(&good[8..]);
    other.truncate(other.len() - 8);
    let e = salvage_bytes(&other, Path::new("o.png")).err().map(|e| e.to_string());
    assert!(e.is_some_and(|e| e.contains("bad magic")));
    assert!(salvage_bytes(&[0u8; 64], Path::new("z")).is_err());
}
