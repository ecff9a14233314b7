//! Salvage, verify and the demo reader on arbitrary bytes after the MCAP magic: never panic, never try to
//! allocate from a corrupt length.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut buf = b"\x89MCAP0\r\n".to_vec();
    buf.extend_from_slice(data);
    let name = std::path::Path::new("fuzz.mcap");
    let s = demo_log::salvage_bytes(&buf, name).expect("magic present");
    assert!(s.report.bytes_used <= buf.len() as u64);
    assert_eq!(s.report.messages as usize, s.messages.len());
    let _ = demo_log::read_demo_bytes(&buf, name);
    let v = demo_log::verify_bytes(&buf, name).expect("magic present");
    assert!(v.chunks.iter().all(|c| c.offset < buf.len() as u64));
    assert_eq!(v.is_ok(), v.problems.is_empty());
});
