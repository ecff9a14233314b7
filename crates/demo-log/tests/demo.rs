mod common;

use common::*;
use demo_log::*;
use std::collections::BTreeMap;

fn opts_small() -> WriterOptions {
    WriterOptions { chunk_size: 16 * 1024, flush_every_steps: 10, compression_level: 0 }
}

#[test]
fn round_trip_steps_and_metadata() {
    let d = tmpdir("roundtrip");
    let log = HandLog {
        header: hand_header(),
        frames: (0..5).map(|i| hand_frame(i, ur3_kin::HandLayout::MediaPipe)).collect(),
    };
    let log_path = d.join("hand.jsonl");
    log.write_jsonl(&log_path).unwrap();
    let mut m = meta(3);
    m.source_handlog = Some(log_path.clone());
    let p = d.join("ep3.mcap");
    let n = 57;
    let mut w = DemoWriter::create(&p, &m).unwrap();
    assert!(partial_path(&p).exists() && !p.exists(), "writes go to PATH.partial until finish");
    for i in 0..n {
        w.write_step(&step(i, n, 80, 7)).unwrap();
    }
    let stats = w
        .finish(&EpisodeSummary { success: true, extra: BTreeMap::from([("picked".into(), "true".into())]) })
        .unwrap();
    assert!(p.exists() && !partial_path(&p).exists());
    assert_eq!(stats.steps, n);
    let ep = read_demo(&p).unwrap();
    assert_eq!((ep.len(), ep.obs_dim, ep.act_dim), (n as usize, 80, 7));
    for i in 0..n as usize {
        let s = step(i as u64, n, 80, 7);
        assert_eq!(&ep.obs[i * 80..(i + 1) * 80], &s.obs[..], "obs row {i} is bit-exact");
        assert_eq!(&ep.actions[i * 7..(i + 1) * 7], &s.action[..]);
        assert_eq!(ep.rewards[i], s.reward as f32);
        assert_eq!(ep.terminated[i], s.terminated);
        assert_eq!(ep.truncated[i], s.truncated);
        assert_eq!(ep.t[i], s.t);
    }
    let sha = sha256_hex(&std::fs::read(&log_path).unwrap());
    assert_eq!(sha.len(), 64);
    let md = &ep.meta;
    assert_eq!(md["task"], "suction");
    assert_eq!(md["seed"], "45");
    assert_eq!(md["episode"], "3");
    assert_eq!(md["robot_model"], "ur3");
    assert_eq!(md["success"], "true");
    assert_eq!(md["picked"], "true");
    assert_eq!(md["length"], n.to_string());
    assert_eq!(md["format"], DEMO_FORMAT);
    assert_eq!(md["format_version"], "1");
    assert_eq!(md["source_handlog_sha256"], sha);
    assert_eq!(md["source_handlog"], log_path.display().to_string());
    assert_eq!(md["gesture_model"], "svm-test");
    assert_eq!(md["hand_layout"], "mediapipe");
    assert_eq!(md["obs_dim"], "80");
    assert_eq!(md["total_reward"], "2");
}

#[test]
fn identical_input_gives_identical_bytes() {
    let d = tmpdir("determinism");
    let a = d.join("a.mcap");
    let b = d.join("b.mcap");
    write_demo(&a, 0, 120, 40, 7, WriterOptions::default());
    write_demo(&b, 0, 120, 40, 7, WriterOptions::default());
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

/// The committed digest of a tiny demo. A change here means the file format changed: bump
/// DEMO_FORMAT_VERSION / the schema version if readers are affected, then update the digest.
/// The file embeds the URDF from ur3-kin; its digest is checked first so that a URDF change is
/// reported as such.
const GOLDEN_SHA256: &str = "81394afedbf332581a15482ad31ffd68b24b04e3b596b2fd7b4bb24585c15dae";
const GOLDEN_URDF_SHA256: &str = "06cb368f83c7f627ef1ac9a1e4f6df4ede420cc1a08d16666576fd3a0a3a73cb";

#[test]
fn golden_bytes() {
    let urdf = sha256_hex(ur3_kin::urdf::to_urdf_string(&ur3_kin::UR3).as_bytes());
    assert_eq!(urdf, GOLDEN_URDF_SHA256, "ur3-kin's URDF changed: update both digests");
    let d = tmpdir("golden");
    let p = d.join("golden.mcap");
    write_demo(&p, 1, 12, 6, 7, WriterOptions::default());
    let got = sha256_hex(&std::fs::read(&p).unwrap());
    assert_eq!(got, GOLDEN_SHA256, "golden demo digest changed");
}

#[test]
fn tf_chain_composes_to_forward_kinematics() {
    let mut rng = 0x2545F4914F6CDD1Du64;
    for _ in 0..200 {
        let mut q = [0.0; 6];
        for x in &mut q {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            *x = (rng % 10_000) as f64 / 10_000.0 * 12.0 - 6.0;
        }
        let chain = link_transforms(&ur3_kin::UR3, &q);
        assert_eq!(chain.len(), LINK_FRAMES.len());
        let mut pose = ur3_kin::Pose::identity();
        let mut parent = BASE_FRAME;
        for ((p, c, rel), want) in chain.iter().zip(LINK_FRAMES) {
            assert_eq!((*p, *c), (parent, want));
            pose *= rel;
            parent = c;
        }
        let fk = ur3_kin::fk(&ur3_kin::UR3, &q);
        assert!((pose.translation.vector - fk.translation.vector).norm() < 1e-12);
        assert!(pose.rotation.angle_to(&fk.rotation) < 1e-9);
    }
}

#[test]
fn urdf_is_attached_and_metadata_written_first() {
    let d = tmpdir("attach");
    let p = d.join("a.mcap");
    write_demo(&p, 0, 5, 4, 7, WriterOptions::default());
    let buf = std::fs::read(&p).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().unwrap();
    assert_eq!(summary.attachment_indexes.len(), 1);
    let a = mcap::read::attachment(&buf, &summary.attachment_indexes[0]).unwrap();
    assert_eq!(a.name, "ur3.urdf");
    assert_eq!(&a.data[..], ur3_kin::urdf::to_urdf_string(&ur3_kin::UR3).as_bytes());
    let names: Vec<_> = summary.metadata_indexes.iter().map(|m| m.name.clone()).collect();
    assert_eq!(names, ["episode_start", "episode"]);
    let topics: BTreeMap<_, _> = summary
        .channels
        .values()
        .map(|c| (c.topic.clone(), c.schema.as_ref().unwrap().name.clone()))
        .collect();
    assert_eq!(topics["/demo/step"], "mimicrete.DemoStep.v1");
    assert_eq!(topics["/tf"], "foxglove.FrameTransforms");
    assert_eq!(topics["/scene"], "foxglove.SceneUpdate");
    assert_eq!(topics["/events"], "foxglove.Event");
    assert_eq!(topics["/hand/joints"], "mimicrete.HandFrame.v1");
    let stats = summary.stats.unwrap();
    // 5 steps, 5 hand frames, 5 tf, 1 scene, events: 1 gesture change + success.
    assert_eq!(stats.message_count, 5 + 5 + 5 + 1 + 2);
}

#[test]
fn messages_have_monotonic_log_times_and_events() {
    let d = tmpdir("events");
    let p = d.join("a.mcap");
    write_demo(&p, 0, 40, 4, 7, WriterOptions::default());
    let buf = std::fs::read(&p).unwrap();
    let mut last = 0;
    let mut events = Vec::new();
    for m in mcap::MessageStream::new(&buf).unwrap() {
        let m = m.unwrap();
        assert!(m.log_time >= last);
        last = m.log_time;
        if m.channel.topic == "/events" {
            let v: serde_json::Value = serde_json::from_slice(&m.data).unwrap();
            events.push(v["event_type"]["name"].as_str().unwrap().to_string());
        }
    }
    // gestures: hold (0..15), suction (15..30), hold (30..40); pick at 10; success at the end.
    assert_eq!(events, ["gesture_change", "pick", "gesture_change", "gesture_change", "success"]);
}

/// Messages per chunk of a complete file, with each chunk's end offset.
fn chunk_extents(buf: &[u8]) -> Vec<(u64, usize)> {
    let summary = mcap::Summary::read(buf).unwrap().unwrap();
    summary
        .chunk_indexes
        .iter()
        .map(|ci| {
            let n = summary.stream_chunk(buf, ci).unwrap().count();
            (ci.chunk_start_offset + ci.chunk_length, n)
        })
        .collect()
}

#[test]
fn cut_at_each_tenth_gives_back_every_complete_message() {
    let d = tmpdir("cut");
    let p = d.join("full.mcap");
    write_demo(&p, 0, 200, 80, 7, opts_small());
    let full = std::fs::read(&p).unwrap();
    let chunks = chunk_extents(&full);
    assert!(chunks.len() >= 10, "the test needs many chunks, got {}", chunks.len());
    let all: Vec<_> = mcap::MessageStream::new(&full).unwrap().map(|m| m.unwrap()).collect();
    for k in 1..10 {
        let cut = full.len() * k / 10;
        let expected: usize = chunks.iter().filter(|(end, _)| *end as usize <= cut).map(|(_, n)| n).sum();
        let cut_path = d.join(format!("cut{k}.mcap"));
        std::fs::write(&cut_path, &full[..cut]).unwrap();
        let (msgs, report) = salvage(&cut_path).unwrap();
        assert!(!report.complete);
        assert_eq!(msgs.len(), expected, "cut at {k}/10 ({cut} bytes)");
        assert!(expected > 0 || k == 1);
        for (got, want) in msgs.iter().zip(&all) {
            assert_eq!(got.topic, want.channel.topic);
            assert_eq!(got.log_time, want.log_time);
            assert_eq!(got.data, &want.data[..]);
        }
        // The cut file is refused by the reader, with a pointer to salvage.
        let e = read_demo(&cut_path).unwrap_err().to_string();
        assert!(e.contains("salvage"), "{e}");
        // The rewritten file is complete and holds the recovered steps.
        let out = d.join(format!("fixed{k}.mcap"));
        let r = salvage_to(&cut_path, &out).unwrap();
        assert_eq!(r.messages as usize, expected);
        let ep = read_demo(&out).unwrap();
        let steps = msgs.iter().filter(|m| m.topic == TOPIC_STEP).count();
        assert_eq!(ep.len(), steps);
        let whole = read_demo(&p).unwrap();
        assert_eq!(&ep.obs[..], &whole.obs[..steps * 80]);
        assert_eq!(ep.meta["task"], "suction", "episode_start metadata survives the cut");
    }
}

#[test]
fn salvage_of_a_complete_file_recovers_everything() {
    let d = tmpdir("salvage-full");
    let p = d.join("a.mcap");
    let stats = write_demo(&p, 0, 30, 8, 7, opts_small());
    let (msgs, r) = salvage(&p).unwrap();
    assert!(r.complete);
    assert_eq!(r.stopped_because, None);
    assert_eq!(msgs.len() as u64, stats.messages);
    assert_eq!((r.metadata, r.attachments), (2, 1));
    assert_eq!(r.chunks_ok, stats.chunks);
}

#[test]
fn a_damaged_chunk_loses_only_itself() {
    let d = tmpdir("damaged");
    let p = d.join("a.mcap");
    write_demo(&p, 0, 200, 80, 7, opts_small());
    let mut buf = std::fs::read(&p).unwrap();
    let summary = mcap::Summary::read(&buf).unwrap().unwrap();
    let ci = &summary.chunk_indexes[3];
    let lost = summary.stream_chunk(&buf, ci).unwrap().count();
    let total: usize = mcap::MessageStream::new(&buf).unwrap().count();
    // Flip bytes in the middle of chunk 3's compressed data.
    let mid = (ci.chunk_start_offset + ci.chunk_length / 2) as usize;
    for b in &mut buf[mid..mid + 16] {
        *b ^= 0x5a;
    }
    let s = salvage_bytes(&buf, std::path::Path::new("damaged.mcap")).unwrap();
    assert_eq!(s.report.chunks_lost, 1);
    assert_eq!(s.messages.len(), total - lost);
    // The reader refuses the file (CRC checked before any record inside the chunk is trusted).
    let e = read_demo_bytes(&buf, std::path::Path::new("damaged.mcap")).unwrap_err().to_string();
    assert!(e.starts_with("damaged.mcap: damaged or incomplete MCAP ("), "{e}");
}

#[test]
fn dropping_without_finish_leaves_a_readable_partial_file() {
    let d = tmpdir("drop");
    let p = d.join("a.mcap");
    {
        let mut w = DemoWriter::create(&p, &meta(0)).unwrap();
        for i in 0..20 {
            w.write_step(&step(i, 100, 8, 7)).unwrap();
        }
    }
    assert!(!p.exists());
    let ep = read_demo(partial_path(&p)).unwrap();
    assert_eq!(ep.len(), 20);
    assert_eq!(ep.meta["task"], "suction");
    assert!(!ep.meta.contains_key("success"));
}

#[test]
fn writer_rejects_bad_steps() {
    let d = tmpdir("bad-steps");
    let mut w = DemoWriter::create(d.join("a.mcap"), &meta(0)).unwrap();
    w.write_step(&step(0, 10, 8, 7)).unwrap();
    let e = |w: &mut DemoWriter, s: StepRecord| w.write_step(&s).unwrap_err().to_string();
    assert_eq!(e(&mut w, step(2, 10, 8, 7)), "step number 2 but 1 steps were written");
    let mut s = step(1, 10, 8, 7);
    s.t = -0.5;
    assert!(e(&mut w, s).contains("not a finite, non-negative"));
    let mut s = step(1, 10, 8, 7);
    s.obs[3] = f32::NAN;
    assert_eq!(e(&mut w, s), "step 1: obs[3] is NaN");
    assert_eq!(
        e(&mut w, step(1, 10, 9, 7)),
        "step 1: obs/action lengths 9/7 differ from the first step's 8/7"
    );
    w.write_step(&step(1, 10, 8, 7)).unwrap();
    let mut s = step(2, 10, 8, 7);
    s.t = 0.01;
    assert_eq!(
        e(&mut w, s),
        "step 2: time 0.01 s is before the last message written (0.04 s); log times must not decrease"
    );
    let mut s = step(2, 10, 8, 7);
    s.terminated = true;
    w.write_step(&s).unwrap();
    assert!(e(&mut w, step(3, 10, 8, 7)).contains("already ended"));
    let mut bad = meta(0);
    bad.robot_model = "ur4".into();
    assert_eq!(
        DemoWriter::create(d.join("b.mcap"), &bad).err().unwrap().to_string(),
        "unknown robot model \"ur4\""
    );
    let mut w = DemoWriter::create(d.join("c.mcap"), &meta(0)).unwrap();
    let mut f = hand_frame(0, ur3_kin::HandLayout::OpenXr);
    assert_eq!(
        w.write_hand_frame(&f, 0.0).unwrap_err().to_string(),
        "hand frame has 26 joints, layout mediapipe has 21"
    );
    f.joints.truncate(21);
    f.joints[0][1] = f64::INFINITY;
    assert_eq!(w.write_hand_frame(&f, 0.0).unwrap_err().to_string(), "hand frame has a non-finite value");
}

#[test]
fn directory_loader_concatenates_in_name_order() {
    let d = tmpdir("dir");
    let lens = [30u64, 12, 25];
    for (i, n) in lens.iter().enumerate() {
        write_demo(&d.join(format!("ep{i:03}.mcap")), i as u64, *n, 16, 7, WriterOptions::default());
    }
    // A leftover partial file is not a demo.
    std::fs::write(d.join("ep999.mcap.partial"), b"junk").unwrap();
    let ds = load_dataset(&d).unwrap();
    let total: u64 = lens.iter().sum();
    assert_eq!(ds.rewards.len() as u64, total);
    assert_eq!(ds.obs.len() as u64, total * 16);
    assert_eq!(ds.actions.len() as u64, total * 7);
    assert_eq!(ds.files.len(), 3);
    let mut want = Vec::new();
    for (i, n) in lens.iter().enumerate() {
        want.extend(std::iter::repeat_n(i as u32, *n as usize));
    }
    assert_eq!(ds.episode, want);
    // Row 30 is episode 1's first step.
    assert_eq!(&ds.obs[30 * 16..31 * 16], &step(0, 12, 16, 7).obs[..]);
    assert_eq!(ds.terminated.iter().filter(|&&t| t).count(), 3);
    assert_eq!(ds.metas[2]["episode"], "2");
    let e = load_dataset(tmpdir("empty")).unwrap_err().to_string();
    assert!(e.ends_with("no *.mcap demos in this directory"), "{e}");
}

#[test]
fn reader_refuses_non_demos() {
    let d = tmpdir("nondemo");
    let p = d.join("x.mcap");
    std::fs::write(&p, b"not an mcap file at all").unwrap();
    let e = read_demo(&p).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: ", p.display())), "{e}");
    let e = salvage(&p).unwrap_err().to_string();
    assert!(e.ends_with("not an MCAP file (bad magic)"), "{e}");
}

mod mutations {
    use super::*;
    use proptest::prelude::*;
    use std::sync::OnceLock;

    fn full() -> &'static (Vec<u8>, usize) {
        static F: OnceLock<(Vec<u8>, usize)> = OnceLock::new();
        F.get_or_init(|| {
            let d = tmpdir("mutations");
            let p = d.join("a.mcap");
            let s = write_demo(
                &p,
                0,
                60,
                16,
                7,
                WriterOptions { chunk_size: 4096, flush_every_steps: 5, compression_level: 0 },
            );
            (std::fs::read(&p).unwrap(), s.messages as usize)
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// Corrupted and cut files: salvage and the reader never panic, salvage never returns more
        /// messages than were written, and what it returns is a prefix-ordered subset.
        #[test]
        fn prop_corrupt_files_are_handled(
            flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..6),
            cut in any::<prop::sample::Index>(),
        ) {
            let (buf, total) = full();
            let mut b = buf.clone();
            for (i, x) in &flips {
                let k = 8 + i.index(b.len() - 8);
                b[k] ^= x | 1;
            }
            let keep = 8 + cut.index(b.len() - 8 + 1);
            b.truncate(keep);
            let name = std::path::Path::new("m.mcap");
            let s = salvage_bytes(&b, name).unwrap();
            prop_assert!(s.messages.len() <= *total);
            prop_assert!(s.report.bytes_used as usize <= b.len());
            let mut last = 0;
            for m in &s.messages {
                prop_assert!(m.log_time >= last);
                last = m.log_time;
            }
            if let Ok(ep) = read_demo_bytes(&b, name) {
                prop_assert!(ep.len() <= 60);
            }
        }
    }
}

#[test]
fn steps_with_their_link_transforms_given_write_the_same_bytes() {
    let d = tmpdir("with_links");
    let (a, b) = (d.join("a.mcap"), d.join("b.mcap"));
    let n = 30;
    let mut wa = DemoWriter::create(&a, &meta(0)).unwrap();
    let mut wb = DemoWriter::create(&b, &meta(0)).unwrap();
    for i in 0..n {
        let s = step(i, n, 12, 7);
        wa.write_step(&s).unwrap();
        wb.write_step_with_links(&s, &link_transforms(&ur3_kin::UR3, &s.joints)).unwrap();
    }
    let done = EpisodeSummary { success: true, ..Default::default() };
    wa.finish(&done).unwrap();
    wb.finish(&done).unwrap();
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    // a chain of the wrong length is refused, naming the step
    let mut w = DemoWriter::create(d.join("c.mcap"), &meta(0)).unwrap();
    let s = step(0, n, 12, 7);
    let mut links = link_transforms(&ur3_kin::UR3, &s.joints);
    links.pop();
    let e = w.write_step_with_links(&s, &links).unwrap_err().to_string();
    assert!(e.contains("step 0: 7 link transforms, the arm's chain has 8"), "{e}");
}

/// A live session's stage times: a sixth channel added at the first one (other demos keep five),
/// written after their steps at the latest log time, recovered by salvage; the demo still loads.
#[test]
fn stage_times_get_their_own_channel_after_the_steps() {
    let d = tmpdir("stage-times");
    let p = d.join("live.mcap");
    let mut w = DemoWriter::create(&p, &meta(0)).unwrap();
    let st = |step: u64, page: Option<f64>| StageTimes {
        step,
        seq: 100 + step,
        capture_ms: 1000.0 + 40.0 * step as f64,
        sent_ms: 1001.5 + 40.0 * step as f64,
        server_recv_ms: 5.0 + 40.0 * step as f64,
        state_sent_ms: Some(5.4 + 40.0 * step as f64),
        page_recv_ms: page,
    };
    let err = w.write_stage_times(&st(0, None)).unwrap_err().to_string();
    assert!(err.contains("stage times of step 0: only 0 steps written"), "{err}");
    for i in 0..6 {
        w.write_step(&step(i, 6, 8, 7)).unwrap();
        if i >= 2 {
            // Step i - 2's state was acknowledged two frames later; the last two never.
            w.write_stage_times(&st(i - 2, Some(1010.0 + 40.0 * (i - 2) as f64))).unwrap();
        }
    }
    w.write_stage_times(&st(4, None)).unwrap();
    let bad = StageTimes { sent_ms: f64::NAN, ..st(5, None) };
    assert!(w.write_stage_times(&bad).unwrap_err().to_string().contains("non-finite"));
    w.write_stage_times(&st(5, None)).unwrap();
    w.finish(&EpisodeSummary { success: false, extra: BTreeMap::new() }).unwrap();
    assert_eq!(read_demo(&p).unwrap().len(), 6);
    let (msgs, r) = salvage(&p).unwrap();
    assert!(r.complete && r.messages_unattributed == 0);
    let stage: Vec<serde_json::Value> = msgs
        .iter()
        .filter(|m| m.topic == TOPIC_STAGE_TIMES)
        .map(|m| serde_json::from_slice(&m.data).unwrap())
        .collect();
    assert_eq!(stage.len(), 6);
    assert_eq!(stage[1]["step"], 1);
    assert_eq!(stage[1]["seq"], 101);
    assert_eq!(stage[1]["page_recv_ms"], 1050.0);
    assert!(stage[5]["page_recv_ms"].is_null());
    let mut last = 0;
    for m in &msgs {
        assert!(m.log_time >= last, "log times do not decrease");
        last = m.log_time;
    }
    // A demo without stage times has no such channel.
    let q = d.join("plain.mcap");
    write_demo(&q, 0, 6, 8, 7, opts_small());
    let (msgs, _) = salvage(&q).unwrap();
    assert!(msgs.iter().all(|m| m.topic != TOPIC_STAGE_TIMES));
}

#[test]
fn a_rows_objects_get_frames_of_their_own_on_tf() {
    let d = tmpdir("row-frames");
    let p = d.join("row.mcap");
    let mut w = DemoWriter::create(&p, &meta(0)).unwrap();
    let pose = |x: f64| Pose { position: [x, 0.4, 0.005], orientation: [0.0, 0.0, 0.0, 1.0] };
    let n = 4;
    for i in 0..n {
        let mut s = step(i, n, 8, 7);
        s.row_poses = vec![pose(-0.2 + 0.01 * i as f64), pose(-0.03), pose(0.14)];
        w.write_step(&s).unwrap();
    }
    w.finish(&EpisodeSummary::default()).unwrap();
    let (msgs, _) = salvage(&p).unwrap();
    let tfs: Vec<serde_json::Value> = msgs
        .iter()
        .filter(|m| m.topic == TOPIC_TF)
        .map(|m| serde_json::from_slice(&m.data).unwrap())
        .collect();
    assert_eq!(tfs.len(), n as usize);
    for (i, tf) in tfs.iter().enumerate() {
        let t = tf["transforms"].as_array().unwrap();
        let children: Vec<&str> = t.iter().map(|x| x["child_frame_id"].as_str().unwrap()).collect();
        // the chain, the current tile, then one frame per object of the row, each under base
        assert_eq!(&children[..8], &LINK_FRAMES[..]);
        assert_eq!(&children[8..], [TILE_FRAME, ROW_FRAMES[0], ROW_FRAMES[1], ROW_FRAMES[2]]);
        assert!(t[8..].iter().all(|x| x["parent_frame_id"] == BASE_FRAME));
        let x0 = t[9]["translation"]["x"].as_f64().unwrap();
        assert!((x0 - (-0.2 + 0.01 * i as f64)).abs() < 1e-12, "{x0}");
        assert_eq!(t[11]["translation"]["x"].as_f64().unwrap(), 0.14);
    }
    // one object: no row frames, as every demo before the row
    write_demo(&d.join("one.mcap"), 0, 3, 8, 7, WriterOptions::default());
    let (msgs, _) = salvage(d.join("one.mcap")).unwrap();
    let tf: serde_json::Value =
        serde_json::from_slice(&msgs.iter().find(|m| m.topic == TOPIC_TF).unwrap().data).unwrap();
    assert_eq!(tf["transforms"].as_array().unwrap().len(), 9);
    // more objects than frames, or a pose that is not finite: refused, naming the step
    let mut w = DemoWriter::create(d.join("bad.mcap"), &meta(0)).unwrap();
    let mut s = step(0, 3, 8, 7);
    s.row_poses = vec![pose(0.0); ROW_FRAMES.len() + 1];
    assert_eq!(
        w.write_step(&s).unwrap_err().to_string(),
        "step 0: 9 row objects, a demo has frames for at most 8"
    );
    s.row_poses = vec![pose(f64::NAN)];
    assert_eq!(w.write_step(&s).unwrap_err().to_string(), "step 0: non-finite reward, joints or pose");
    // frame_numbers: the row's frames after the tile's; a row too long is refused
    let q = [0.1, -1.0, 1.2, -0.4, 0.3, 0.9];
    let f = frame_numbers("ur3", &q, &pose(0.0), &[pose(-0.2), pose(0.0)]).unwrap();
    assert_eq!(f.len(), 11);
    assert_eq!(f[ROW_FRAMES[1]], pose(0.0).to_numbers());
    assert!(!f.contains_key(ROW_FRAMES[2]));
    assert!(frame_numbers("ur3", &q, &pose(0.0), &[pose(0.0); 9]).is_err());
}

/// A deploy log's ticks: their own channel (`/deploy/tick`, `mimicrete.DeployTick.v1`) after
/// the steps, vectors of the wrong length and non-finite numbers refused, a raw action that was
/// not finite kept as null; salvage recovers them and the demo still loads.
#[test]
fn deploy_ticks_get_their_own_channel_after_the_steps() {
    let d = tmpdir("deploy-ticks");
    let p = d.join("deploy.mcap");
    let mut w = DemoWriter::create(&p, &meta(0)).unwrap();
    let tick = |step: u64| DeployTick {
        step,
        t: 0.04 * step as f64,
        robot_time: 100.0 + 0.04 * step as f64,
        q_read: vec![0.1; 6],
        tcp_read: vec![0.2; 6],
        safety_mode: 1,
        digital_out: 1,
        tile_pose: vec![0.1, 0.32, 0.0],
        tile_source: "fixed".into(),
        raw_action: vec![Some(0.5), None, Some(-1.0), Some(0.0), Some(0.0), Some(0.0), Some(1.0)],
        command_q: vec![0.12; 6],
        suction: step > 1,
        gates: if step == 2 { vec!["workspace".into()] } else { vec![] },
        sent: false,
        latency_ms: 1.5,
    };
    let err = w.write_deploy_tick(&tick(0)).unwrap_err().to_string();
    assert!(err.contains("deploy tick 0: only 0 steps written"), "{err}");
    for i in 0..4 {
        w.write_step(&step(i, 4, 8, 7)).unwrap();
        w.write_deploy_tick(&tick(i)).unwrap();
    }
    let short = DeployTick { command_q: vec![0.0; 5], ..tick(3) };
    let err = w.write_deploy_tick(&short).unwrap_err().to_string();
    assert!(err.contains("command_q has 5 numbers, expected 6"), "{err}");
    let nan = DeployTick { latency_ms: f64::NAN, ..tick(3) };
    assert!(w.write_deploy_tick(&nan).unwrap_err().to_string().contains("non-finite"));
    w.finish(&EpisodeSummary::default()).unwrap();
    assert_eq!(read_demo(&p).unwrap().len(), 4);
    let (msgs, r) = salvage(&p).unwrap();
    assert!(r.complete && r.messages_unattributed == 0);
    let ticks: Vec<serde_json::Value> = msgs
        .iter()
        .filter(|m| m.topic == TOPIC_DEPLOY_TICK)
        .map(|m| serde_json::from_slice(&m.data).unwrap())
        .collect();
    assert_eq!(ticks.len(), 4);
    assert_eq!(ticks[2]["gates"][0], "workspace");
    assert!(ticks[1]["raw_action"][1].is_null());
    assert_eq!(ticks[3]["tile_source"], "fixed");
    let back: DeployTick = serde_json::from_value(ticks[3].clone()).unwrap();
    assert_eq!(back, tick(3));
}
