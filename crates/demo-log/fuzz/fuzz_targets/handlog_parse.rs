//! The hand-log parser on arbitrary text: it must never panic, a strict error must point inside
//! the text, lenient mode must accept whatever strict accepts (keeping only tracked frames), and
//! whatever parses must survive a write/parse round trip unchanged.
#![no_main]

use demo_log::{HandLog, ParseMode};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let lines = text.lines().count().max(1);
    let strict = HandLog::parse_str(text, "fuzz", ParseMode::Strict);
    let lenient = HandLog::parse_str(text, "fuzz", ParseMode::Lenient);
    match &strict {
        Ok((log, rep)) => {
            assert_eq!(rep.kept, log.frames.len());
            let (len, lrep) = lenient.as_ref().expect("lenient accepts what strict accepts");
            assert_eq!(len.frames.len(), log.frames.iter().filter(|f| f.tracked).count());
            assert_eq!(lrep.invalid_skipped, 0);
            let out = log.to_jsonl().expect("a parsed log is valid");
            let (back, _) = HandLog::parse_str(&out, "fuzz-out", ParseMode::Strict).expect("round trip parses");
            assert_eq!(&back, log);
        }
        Err(e) => {
            assert!(e.line >= 1 && e.line <= lines, "error line {} outside 1..={lines}", e.line);
            if e.line == 1 {
                assert!(lenient.is_err(), "a header error aborts in lenient mode too");
            }
        }
    }
    if let Ok((len, rep)) = &lenient {
        assert!(len.frames.iter().all(|f| f.tracked));
        assert!(len.frames.windows(2).all(|w| w[0].t <= w[1].t));
        assert_eq!(rep.kept + rep.untracked_skipped + rep.invalid_skipped, rep.frame_lines);
    }
});
