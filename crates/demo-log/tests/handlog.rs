mod common;

use common::*;
use demo_log::*;
use proptest::prelude::*;
use ur3_kin::{HandLayout, Handedness, Space};

const HDR: &str = r#"{"format":"mimicrete.handlog","version":1,"layout":"mediapipe","space":"openxr","handedness":"right","units":"m"}"#;

fn joints_json(n: usize) -> String {
    let v: Vec<String> = (0..n).map(|j| format!("[{},{},{}]", 0.01 * j as f64, 1.0, -0.5)).collect();
    format!("[{}]", v.join(","))
}

fn frame_line(t: f64, tracked: bool, n: usize) -> String {
    format!(r#"{{"t":{t},"tracked":{tracked},"joints":{}}}"#, joints_json(n))
}

fn good_text(frames: usize) -> String {
    let mut s = format!("{HDR}\n");
    for i in 0..frames {
        s.push_str(&frame_line(i as f64 * 0.01, true, 21));
        s.push('\n');
    }
    s
}

fn strict_err(text: &str) -> String {
    HandLog::parse_str(text, "hand.jsonl", ParseMode::Strict).unwrap_err().to_string()
}

#[test]
fn a_good_log_parses() {
    let (log, rep) = HandLog::parse_str(&good_text(4), "hand.jsonl", ParseMode::Strict).unwrap();
    assert_eq!(log.frames.len(), 4);
    assert_eq!(log.header.layout, HandLayout::MediaPipe);
    assert_eq!(log.header.space, Space::OpenXr);
    assert_eq!(log.header.handedness, Handedness::Right);
    assert_eq!(log.frames[2].joints[3], [0.03, 1.0, -0.5]);
    assert_eq!(rep, ParseReport { frame_lines: 4, kept: 4, ..Default::default() });
}

#[test]
fn every_layout_needs_its_joint_count() {
    for (layout, n) in [("openxr", 26), ("webxr", 25), ("meta_ovr", 24), ("mediapipe", 21)] {
        let hdr = HDR.replace("mediapipe", layout);
        let ok = format!("{hdr}\n{}\n", frame_line(0.0, true, n));
        assert!(HandLog::parse_str(&ok, "h", ParseMode::Strict).is_ok(), "{layout}");
        let bad = format!("{hdr}\n{}\n", frame_line(0.0, true, n - 1));
        assert_eq!(
            strict_err(&bad),
            format!("hand.jsonl:2: wrong joint count: {} joints, layout {layout} has {n}", n - 1)
        );
    }
}

#[test]
fn bad_header_cases() {
    assert_eq!(strict_err(""), "hand.jsonl:1: missing header: the file is empty");
    assert_eq!(strict_err("\n{}\n"), "hand.jsonl:1: missing header: line 1 is blank");
    assert_eq!(
        strict_err(&format!("{}\n", frame_line(0.0, true, 21))),
        "hand.jsonl:1: missing header: line 1 has no \"format\" field (expected \"format\":\"mimicrete.handlog\")"
    );
    assert_eq!(strict_err("[1,2]\n"), "hand.jsonl:1: missing header: line 1 is an array, not a JSON object");
    assert!(
        strict_err("hello\n")
            .starts_with("hand.jsonl:1: missing header: line 1 is not a JSON object (invalid JSON:")
    );
    // Header edits and the message each must give (file:line: reason).
    let edits: [(&str, &str, &str); 12] = [
        (
            "mimicrete.handlog",
            "other.log",
            "unknown format \"other.log\" in header (expected \"mimicrete.handlog\")",
        ),
        (r#""version":1"#, r#""version":2"#, "header: unsupported version 2 (this reader knows version 1)"),
        (r#""version":1,"#, "", "header: missing field \"version\""),
        (
            "mediapipe",
            "leapmotion",
            "header: unknown layout \"leapmotion\" (known: openxr, webxr, meta_ovr, mediapipe)",
        ),
        (r#""layout":"mediapipe","#, "", "header: missing field \"layout\""),
        (
            r#""space":"openxr""#,
            r#""space":"ros""#,
            "header: unknown space \"ros\" (known: openxr, webxr, unity, robot_base)",
        ),
        (r#","space":"openxr""#, "", "header: missing field \"space\""),
        ("right", "both", "header: unknown handedness \"both\" (known: left, right)"),
        (r#","handedness":"right""#, "", "header: missing field \"handedness\""),
        (
            r#""units":"m""#,
            r#""units":"mm""#,
            "header: unknown units \"mm\" (hand logs are in metres: \"m\")",
        ),
        (r#","units":"m""#, "", "header: missing field \"units\""),
        (
            r#""units":"m""#,
            r#""units":"m","episode_seed":-3"#,
            "header: \"episode_seed\" must be a non-negative integer, got -3",
        ),
    ];
    for (from, to, reason) in edits {
        assert_eq!(strict_err(&HDR.replace(from, to)), format!("hand.jsonl:1: {reason}"), "{from} -> {to}");
    }
    assert!(
        strict_err(&HDR.replace(r#""units":"m""#, r#""units":"m","fps":90"#))
            .starts_with("hand.jsonl:1: header: unknown field \"fps\"")
    );
    // A bad header aborts in lenient mode too.
    assert!(HandLog::parse_str(&HDR.replace("mediapipe", "x"), "h", ParseMode::Lenient).is_err());
}

#[test]
fn optional_header_fields_are_read() {
    let hdr = HDR.replace(
        r#""units":"m""#,
        r#""units":"m","task":"suction","episode_seed":18446744073709551615,"source":"synth v1","extra":{"fps":90}"#,
    );
    let (log, _) = HandLog::parse_str(&format!("{hdr}\n"), "h", ParseMode::Strict).unwrap();
    assert_eq!(log.header.task.as_deref(), Some("suction"));
    assert_eq!(log.header.episode_seed, Some(u64::MAX));
    assert_eq!(log.header.source.as_deref(), Some("synth v1"));
    assert_eq!(log.header.extra.as_ref().unwrap()["fps"], 90);
}

#[test]
fn bad_frame_cases() {
    let with = |line: &str| format!("{}{line}\n", good_text(2));
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 20))),
        "hand.jsonl:4: wrong joint count: 20 joints, layout mediapipe has 21"
    );
    // NaN and infinities, as Python's json module writes them, and as an overflowing literal.
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 21).replacen("1,", "NaN,", 1))),
        "hand.jsonl:4: non-finite value (NaN) in joint 0 coordinate y"
    );
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 21).replacen("-0.5", "-Infinity", 1))),
        "hand.jsonl:4: non-finite value (-Infinity) in joint 0 coordinate z"
    );
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 21).replacen("-0.5", "1e999", 1))),
        "hand.jsonl:4: non-finite value: a number overflows to infinity"
    );
    assert_eq!(
        strict_err(&with(r#"{"t":Infinity,"tracked":true,"joints":[]}"#)),
        "hand.jsonl:4: non-finite value (Infinity) in \"t\""
    );
    assert_eq!(
        strict_err(&with(&frame_line(0.001, true, 21))),
        "hand.jsonl:4: time goes backwards: t=0.001 after t=0.01"
    );
    assert_eq!(strict_err(&with(r#"{"tracked":true,"joints":[]}"#)), "hand.jsonl:4: frame has no \"t\"");
    assert_eq!(
        strict_err(&with(r#"{"t":1,"tracked":1,"joints":[]}"#)),
        "hand.jsonl:4: \"tracked\" must be a bool, got a number"
    );
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 21).replace(r#""t""#, r#""time""#))),
        "hand.jsonl:4: unknown frame field \"time\" (known: t, tracked, joints, orientations)"
    );
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 21).replacen("[0,1,-0.5]", "[0,1]", 1))),
        "hand.jsonl:4: joint 0 must be [x, y, z], got 2 numbers"
    );
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 21).replacen("[0,1,-0.5]", r#"[0,"a",1]"#, 1))),
        "hand.jsonl:4: joint 0 coordinate y must be a number, got a string"
    );
    assert_eq!(
        strict_err(&with(&frame_line(0.5, true, 21).replace("}", r#","orientations":[[0,0,0,1]]}"#))),
        "hand.jsonl:4: wrong orientation count: 1 orientations, layout mediapipe has 21 joints"
    );
    assert!(
        strict_err(&with("{oops")).starts_with("hand.jsonl:4: invalid JSON:"),
        "a bad line with its newline is not 'truncated'"
    );
    assert_eq!(strict_err(&with("[1]")), "hand.jsonl:4: a frame must be a JSON object, got an array");
}

#[test]
fn truncated_last_line() {
    let full = good_text(3);
    // Cut in the middle of the last frame: no trailing newline and not valid JSON.
    let cut = &full[..full.len() - 20];
    let e = strict_err(cut);
    assert!(
        e.starts_with("hand.jsonl:4: truncated last line (no newline at end of file and invalid JSON:"),
        "{e}"
    );
    // A complete last line without its newline is fine.
    let (log, _) = HandLog::parse_str(full.trim_end(), "h", ParseMode::Strict).unwrap();
    assert_eq!(log.frames.len(), 3);
    // Lenient mode drops the cut line and keeps the rest.
    let (log, rep) = HandLog::parse_str(cut, "h", ParseMode::Lenient).unwrap();
    assert_eq!(log.frames.len(), 2);
    assert_eq!(rep.invalid_skipped, 1);
    assert_eq!(rep.skipped[0].line, 4);
    assert!(rep.skipped[0].reason.starts_with("truncated last line"));
}

#[test]
fn lenient_mode_counts_and_locates_skipped_lines() {
    let mut s = format!("{HDR}\n");
    s += &(frame_line(0.0, true, 21) + "\n"); // 2 ok
    s += &(frame_line(0.1, false, 21) + "\n"); // 3 untracked
    s += &(frame_line(0.2, true, 20) + "\n"); // 4 bad count
    s += "\n"; // 5 blank: ignored
    s += &(frame_line(0.3, true, 21) + "\n"); // 6 ok
    s += &(frame_line(0.25, true, 21) + "\n"); // 7 backwards
    s += &(frame_line(0.3, true, 21).replacen("1,", "NaN,", 1) + "\n"); // 8 NaN
    s += &(frame_line(0.4, true, 21) + "\n"); // 9 ok
    s += &(frame_line(0.5, false, 21) + "\n"); // 10 untracked
    let (log, rep) = HandLog::parse_str(&s, "h", ParseMode::Lenient).unwrap();
    assert_eq!(log.frames.iter().map(|f| f.t).collect::<Vec<_>>(), [0.0, 0.3, 0.4]);
    assert_eq!(rep.frame_lines, 8);
    assert_eq!(rep.kept, 3);
    assert_eq!(rep.untracked_skipped, 2);
    assert_eq!(rep.invalid_skipped, 3);
    let lines: Vec<_> = rep.skipped.iter().map(|k| k.line).collect();
    assert_eq!(lines, [3, 4, 7, 8, 10]);
    assert_eq!(rep.skipped[0].reason, "untracked frame");
    assert_eq!(rep.skipped[2].reason, "time goes backwards: t=0.25 after t=0.3");
    // Strict mode keeps untracked frames and stops at line 4.
    assert_eq!(strict_err(&s), "hand.jsonl:4: wrong joint count: 20 joints, layout mediapipe has 21");
}

/// A UTF-8 BOM at the start of the file (Windows editors) is accepted; one at the start of a
/// later line (concatenated files) is named; a UTF-16 file is named as such.
#[test]
fn byte_order_marks() {
    let plain = HandLog::parse_str(&good_text(3), "hand.jsonl", ParseMode::Strict).unwrap();
    let bom =
        HandLog::parse_str(&format!("\u{feff}{}", good_text(3)), "hand.jsonl", ParseMode::Strict).unwrap();
    assert_eq!(plain, bom);
    let concatenated = format!("{}\u{feff}{}\n", good_text(2), frame_line(0.5, true, 21));
    assert_eq!(
        strict_err(&concatenated),
        "hand.jsonl:4: line starts with a UTF-8 byte-order mark (BOM), as where two files were concatenated; \
         remove it"
    );
    let (_, rep) = HandLog::parse_str(&concatenated, "hand.jsonl", ParseMode::Lenient).unwrap();
    assert_eq!((rep.kept, rep.invalid_skipped), (2, 1));
    let d = tmpdir("handlog-bom");
    let p = d.join("bom.jsonl");
    std::fs::write(&p, format!("\u{feff}{}", good_text(2))).unwrap();
    assert_eq!(HandLog::from_path(&p, ParseMode::Strict).unwrap().0.frames.len(), 2);
    let utf16: Vec<u8> =
        [0xff, 0xfe].into_iter().chain(good_text(1).encode_utf16().flat_map(|u| u.to_le_bytes())).collect();
    std::fs::write(&p, utf16).unwrap();
    assert_eq!(
        HandLog::from_path(&p, ParseMode::Strict).unwrap_err().to_string(),
        format!(
            "{}:1: not UTF-8 text: the file starts with a UTF-16 byte-order mark (BOM); save it as UTF-8",
            p.display()
        )
    );
}

#[test]
fn files_report_their_path_and_utf8_errors() {
    let d = tmpdir("handlog-files");
    let p = d.join("h.jsonl");
    std::fs::write(&p, format!("{HDR}\n{}\n\u{0}", frame_line(0.0, true, 21)).into_bytes()).unwrap();
    let mut bytes = good_text(2).into_bytes();
    bytes.extend_from_slice(b"\xff\xfe\n");
    std::fs::write(&p, &bytes).unwrap();
    assert_eq!(
        HandLog::from_path(&p, ParseMode::Strict).unwrap_err().to_string(),
        format!("{}:4: not UTF-8 text", p.display())
    );
    let missing = d.join("nope.jsonl");
    assert!(
        HandLog::from_path(&missing, ParseMode::Strict)
            .unwrap_err()
            .to_string()
            .starts_with(&format!("{}:1: cannot read:", missing.display()))
    );
}

#[test]
fn writer_round_trip_and_refusals() {
    let d = tmpdir("handlog-write");
    let mut log = HandLog {
        header: hand_header(),
        frames: (0..50).map(|i| hand_frame(i, HandLayout::MediaPipe)).collect(),
    };
    log.frames[4].orientations = Some(vec![[0.0, 0.0, 0.0, 1.0]; 21]);
    let p = d.join("h.jsonl");
    log.write_jsonl(&p).unwrap();
    let (back, rep) = HandLog::from_path(&p, ParseMode::Strict).unwrap();
    assert_eq!(back, log);
    assert_eq!(rep.kept, 50);
    // Lenient drops the untracked ones (i % 7 == 3).
    let (lenient, rep) = HandLog::from_path(&p, ParseMode::Lenient).unwrap();
    assert_eq!(lenient.frames.len(), 50 - 7);
    assert_eq!(rep.untracked_skipped, 7);
    // Invalid content is refused and nothing is written.
    log.frames[10].joints[2][0] = f64::NAN;
    let q = d.join("bad.jsonl");
    assert_eq!(
        log.write_jsonl(&q).unwrap_err().to_string(),
        format!("{}:12: non-finite value in joint 2", q.display())
    );
    assert!(!q.exists() && !partial_path(&q).exists());
    log.frames[10].joints[2][0] = 0.0;
    log.frames[20].t = 0.0;
    assert!(log.to_jsonl().unwrap_err().to_string().starts_with("<memory>:22: time goes backwards"));
}

fn arb_log() -> impl Strategy<Value = HandLog> {
    let layout = prop::sample::select(HandLayout::ALL.to_vec());
    (layout, 0usize..12, any::<bool>(), prop::option::of(any::<u64>())).prop_flat_map(
        |(layout, n, left, seed)| {
            let n_j = layout.joint_count();
            let coord = prop_oneof![
                -10.0f64..10.0,
                Just(0.0),
                Just(-0.0),
                Just(1e-300),
                Just(demo_log::MAX_COORD_M),
                Just(-demo_log::MAX_COORD_M)
            ];
            let frame = (
                0.0f64..1.0,
                any::<bool>(),
                prop::collection::vec([coord.clone(), coord.clone(), coord], n_j),
                any::<bool>(),
            );
            prop::collection::vec(frame, n).prop_map(move |fs| {
                let mut t = 0.0;
                let frames = fs
                    .into_iter()
                    .map(|(dt, tracked, joints, with_o)| {
                        t += dt;
                        HandFrame {
                            t,
                            tracked,
                            orientations: with_o.then(|| vec![[0.0, 0.6, 0.0, 0.8]; n_j]),
                            joints,
                        }
                    })
                    .collect();
                let mut header = HandLogHeader::new(
                    layout,
                    Space::Unity,
                    if left { Handedness::Left } else { Handedness::Right },
                );
                header.episode_seed = seed;
                HandLog { header, frames }
            })
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Writing then strictly parsing gives back exactly the same log (bit-exact floats).
    #[test]
    fn prop_round_trip(log in arb_log()) {
        let text = log.to_jsonl().unwrap();
        let (back, rep) = HandLog::parse_str(&text, "p", ParseMode::Strict).unwrap();
        prop_assert_eq!(&back, &log);
        prop_assert_eq!(rep.kept, log.frames.len());
        let (len, rep) = HandLog::parse_str(&text, "p", ParseMode::Lenient).unwrap();
        prop_assert_eq!(len.frames.len(), log.frames.iter().filter(|f| f.tracked).count());
        prop_assert_eq!(rep.untracked_skipped + rep.kept, log.frames.len());
    }

    /// Replacing one frame line by garbage: strict names exactly that line, lenient drops only it.
    #[test]
    fn prop_one_bad_line_is_located(log in arb_log(), which in any::<prop::sample::Index>(), kind in 0usize..5) {
        prop_assume!(!log.frames.is_empty());
        let text = log.to_jsonl().unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let k = 1 + which.index(log.frames.len());
        let n = log.header.layout.joint_count();
        lines[k] = match kind {
            0 => "{not json".to_string(),
            1 => format!(r#"{{"t":{},"tracked":true,"joints":{}}}"#, log.frames[k - 1].t, joints_json(n + 1)),
            2 => format!(r#"{{"t":{},"tracked":true,"joints":{}}}"#, log.frames[k - 1].t, joints_json(n).replacen("1,", "NaN,", 1)),
            3 => format!(r#"{{"t":-1e300,"tracked":true,"joints":{}}}"#, joints_json(n)),
            _ => "42".to_string(),
        };
        // -1e300 is only "backwards" if some earlier frame exists; a first frame at -1e300 is valid.
        let expect_error = !(kind == 3 && k == 1);
        let bad = lines.join("\n") + "\n";
        let strict = HandLog::parse_str(&bad, "p", ParseMode::Strict);
        if expect_error {
            let e = strict.unwrap_err();
            prop_assert_eq!(e.line, k + 1);
            let (lenient, rep) = HandLog::parse_str(&bad, "p", ParseMode::Lenient).unwrap();
            let tracked_others = log.frames.iter().enumerate().filter(|(i, f)| *i != k - 1 && f.tracked).count();
            // Lenient mode compares times with the last *kept* frame: with no tracked frame before it,
            // the t=-1e300 line is valid there (and kept).
            let lenient_ok = kind == 3 && !log.frames[..k - 1].iter().any(|f| f.tracked);
            prop_assert_eq!(rep.invalid_skipped, usize::from(!lenient_ok));
            prop_assert_eq!(lenient.frames.len(), tracked_others + usize::from(lenient_ok));
        }
    }

    /// The parser never panics, and a strict error always points inside the text.
    #[test]
    fn prop_never_panics(text in "(\\PC{0,40}\n){0,6}\\PC{0,40}", prefix in any::<bool>()) {
        let text = if prefix { format!("{HDR}\n{text}") } else { text };
        let lines = text.lines().count().max(1);
        match HandLog::parse_str(&text, "p", ParseMode::Strict) {
            Ok((log, _)) => prop_assert!(log.frames.len() <= lines),
            Err(e) => prop_assert!(e.line >= 1 && e.line <= lines, "line {} of {}", e.line, lines),
        }
        let _ = HandLog::parse_str(&text, "p", ParseMode::Lenient);
    }
}

#[test]
fn conversion_to_robot_base_uses_the_calibration() {
    let log = HandLog {
        header: hand_header(),
        frames: (0..4).map(|i| hand_frame(i, HandLayout::MediaPipe)).collect(),
    };
    let cal = ur3_kin::Calibration::default(); // OpenXR space, the log's
    let base = log.to_robot_base(&cal, "h").unwrap();
    assert_eq!(base.header.space, Space::RobotBase);
    for (f, g) in log.frames.iter().zip(&base.frames) {
        assert_eq!((f.t, f.tracked), (g.t, g.tracked));
        for (p, q) in f.joints.iter().zip(&g.joints) {
            let want = cal.point_to_base(&ur3_kin::nalgebra::Vector3::new(p[0], p[1], p[2]));
            assert_eq!(*q, [want.x, want.y, want.z]);
        }
    }
    // OpenXR (+Y up) → Base (+Z up): a point 1 m above the origin ends up 1 m higher in Base.
    let up = cal.point_to_base(&ur3_kin::nalgebra::Vector3::new(0.0, 1.0, 0.0));
    let zero = cal.point_to_base(&ur3_kin::nalgebra::Vector3::zeros());
    assert!(((up - zero) - ur3_kin::nalgebra::Vector3::z()).norm() < 1e-12);
    let e = log.to_robot_base(&ur3_kin::Calibration::identity(), "h.jsonl").unwrap_err();
    assert_eq!(
        e.to_string(),
        "h.jsonl:1: calibration is for space robot_base but the log is in space openxr"
    );
}
