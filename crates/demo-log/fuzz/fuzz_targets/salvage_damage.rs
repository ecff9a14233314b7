//! A real demo with fuzzer-chosen damage: bit flips (xor masks at chosen offsets) and an
//! optional cut. Checks, against a ground truth computed from the undamaged file's chunk index
//! with the `mcap` crate: salvage recovers exactly the messages of the intact chunks (a chunk is
//! intact when it lies before the cut and its bytes are unchanged, except for the log-time fields
//! the CRC does not cover, or its compressed records still decompress to the original); the file
//! `salvage_to` writes loads with exactly the recovered steps; `verify` reports any change.
#![no_main]

use demo_log::*;
use libfuzzer_sys::fuzz_target;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

type Msg = (String, u64, Vec<u8>);

struct Base {
    buf: Vec<u8>,
    /// (start, end, messages) of every chunk, by offset.
    chunks: Vec<(usize, usize, Vec<Msg>)>,
    dir: PathBuf,
    obs: Vec<f32>,
}

const OBS: usize = 8;

fn base() -> &'static Base {
    static B: OnceLock<Base> = OnceLock::new();
    B.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("salvage-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("base.mcap");
        let opts = WriterOptions { chunk_size: 2048, flush_every_steps: 4, compression_level: 0 };
        let mut w = DemoWriter::create_with_options(&p, &EpisodeMeta::default(), opts).unwrap();
        let n = 40u64;
        for i in 0..n {
            let t = i as f64 * 0.04;
            let q = [0.1 * t, -1.2, 1.0, -0.5, -1.57, 0.2 * t];
            w.write_step(&StepRecord {
                step: i,
                t,
                obs: (0..OBS).map(|k| ((i as usize * 31 + k) % 97) as f32 * 0.01).collect(),
                action: vec![0.25 * (i % 4) as f32; 3],
                reward: 0.0,
                terminated: i + 1 == n,
                truncated: false,
                gesture: if i < 20 { "hold".into() } else { "suction".into() },
                joints: q,
                ee_pose: Pose::IDENTITY,
                tile_pose: Pose::IDENTITY,
                row_poses: vec![],
                events: vec![],
                scene: vec![],
            })
            .unwrap();
        }
        w.finish(&EpisodeSummary { success: true, ..Default::default() }).unwrap();
        let buf = std::fs::read(&p).unwrap();
        let summary = mcap::Summary::read(&buf).unwrap().unwrap();
        let mut idx = summary.chunk_indexes.clone();
        idx.sort_by_key(|c| c.chunk_start_offset);
        let chunks = idx
            .iter()
            .map(|ci| {
                let msgs = summary
                    .stream_chunk(&buf, ci)
                    .unwrap()
                    .map(|m| {
                        let m = m.unwrap();
                        (m.channel.topic.clone(), m.log_time, m.data.into_owned())
                    })
                    .collect();
                (ci.chunk_start_offset as usize, (ci.chunk_start_offset + ci.chunk_length) as usize, msgs)
            })
            .collect();
        let obs = read_demo(&p).unwrap().obs;
        Base { buf, chunks, dir, obs }
    })
}

fn intact(c: &(usize, usize, Vec<Msg>), orig: &[u8], b: &[u8]) -> bool {
    let (s, e) = (c.0, c.1);
    if e > b.len() {
        return false;
    }
    let changed: Vec<usize> = (s..e).filter(|&i| b[i] != orig[i] && !(s + 9..s + 25).contains(&i)).collect();
    if changed.is_empty() {
        return true;
    }
    let data = s + 53;
    if changed[0] < data {
        return false;
    }
    let n = u64::from_le_bytes(orig[s + 25..s + 33].try_into().unwrap()) as usize;
    let want = zstd::bulk::decompress(&orig[data..e], n).unwrap();
    zstd::bulk::decompress(&b[data..e], n).is_ok_and(|got| got == want)
}

fuzz_target!(|data: &[u8]| {
    let base = base();
    let orig = &base.buf;
    let mut b = orig.clone();
    // Each 5 bytes: u32 offset (mod the length) and an xor mask; mask 0 cuts the file there.
    for op in data.chunks_exact(5).take(16) {
        let at = u32::from_le_bytes(op[..4].try_into().unwrap()) as usize;
        if b.len() <= 8 {
            break;
        }
        let at = 8 + at % (b.len() - 8);
        if op[4] == 0 {
            b.truncate(at);
        } else {
            b[at] ^= op[4];
        }
    }
    let expected: Vec<&Msg> =
        base.chunks.iter().filter(|c| intact(c, orig, &b)).flat_map(|c| c.2.iter()).collect();
    let name = Path::new("fuzz.mcap");
    let s = salvage_bytes(&b, name).expect("the magic is never touched");
    let got: Vec<Msg> = s.messages.iter().map(|m| (m.topic.clone(), m.log_time, m.data.clone())).collect();
    assert!(
        got.len() == expected.len() && got.iter().zip(&expected).all(|(g, e)| g == *e),
        "recovered {} messages, the intact chunks hold {}; changed bytes {:?}, length {}; chunks {:?}; verify {:?}",
        got.len(),
        expected.len(),
        (0..b.len()).filter(|&i| b[i] != orig[i]).collect::<Vec<_>>(),
        b.len(),
        base.chunks.iter().map(|c| (c.0, c.1, intact(c, orig, &b))).collect::<Vec<_>>(),
        verify_bytes(&b, name).map(|v| v.problems).unwrap_or_default()
    );
    let v = verify_bytes(&b, name).unwrap();
    assert_eq!(v.is_ok(), b == *orig, "{:?}", v.problems);
    let inp = base.dir.join("in.mcap");
    let out = base.dir.join("out.mcap");
    std::fs::write(&inp, &b).unwrap();
    match salvage_to(&inp, &out) {
        Ok(_) => {
            let ep = read_demo(&out).expect("a salvaged file loads");
            let steps: Vec<usize> = expected
                .iter()
                .filter(|m| m.0 == TOPIC_STEP)
                .map(|m| serde_json::from_slice::<serde_json::Value>(&m.2).unwrap()["step"].as_u64().unwrap() as usize)
                .collect();
            assert_eq!(ep.len(), steps.len());
            for (row, st) in steps.iter().enumerate() {
                assert_eq!(ep.obs[row * OBS..(row + 1) * OBS], base.obs[st * OBS..(st + 1) * OBS]);
            }
        }
        Err(e) => {
            let e = e.to_string();
            assert!(expected.is_empty() && e.contains("nothing recognisable as a demo survives"), "{e}");
        }
    }
});
