//! `demo-log-bench [--dir DIR] [--episodes 60] [--steps 200] [--obs 80] [--act 7] [--keep]`
//!
//! Writes synthetic demos (full channel set: step, hand frame, tf, scene, events) and prints steps
//! written per second, then the time to load them all into flat arrays. The last line is JSON for
//! `python -m mimicrete.bench demo`.

use demo_log::*;
use std::time::Instant;
use ur3_kin::{HandLayout, Handedness, Space};

fn arg<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> T {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let episodes: u64 = arg(&args, "--episodes", 60);
    let steps: u64 = arg(&args, "--steps", 200);
    let obs_dim: usize = arg(&args, "--obs", 80);
    let act_dim: usize = arg(&args, "--act", 7);
    let keep = args.iter().any(|a| a == "--keep");
    let dir = args
        .iter()
        .position(|a| a == "--dir")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::env::temp_dir().join(format!("demo-log-bench-{}", std::process::id())));
    std::fs::create_dir_all(&dir)?;

    let layout = HandLayout::OpenXr;
    let header = HandLogHeader::new(layout, Space::OpenXr, Handedness::Right);
    let mut bytes = 0u64;
    let mut messages = 0u64;
    let t0 = Instant::now();
    for e in 0..episodes {
        let meta = EpisodeMeta {
            episode: e,
            seed: e,
            hand: Some(header.clone()),
            control_dt: 0.04,
            ..Default::default()
        };
        let mut w = DemoWriter::create(dir.join(format!("episode_{e:04}.mcap")), &meta)?;
        for i in 0..steps {
            let t = i as f64 * 0.04;
            let q = [0.3 * t.sin(), -1.2 + 0.1 * t, 1.0, -0.5, -1.57, 0.2 * t];
            let hand = HandFrame {
                t: t + 12.5,
                tracked: true,
                joints: (0..layout.joint_count()).map(|j| [0.01 * j as f64 + t, 1.2, -0.3]).collect(),
                orientations: None,
            };
            w.write_hand_frame(&hand, t)?;
            w.write_step(&StepRecord {
                step: i,
                t,
                obs: (0..obs_dim).map(|k| ((i as usize * 7 + k) % 101) as f32 * 0.013 - 0.5).collect(),
                action: (0..act_dim).map(|k| ((i as usize + k) % 3) as f32 - 1.0).collect(),
                reward: if i + 1 == steps { 1.0 } else { 0.0 },
                terminated: i + 1 == steps,
                truncated: false,
                gesture: if i < steps / 2 { "hold".into() } else { "suction".into() },
                joints: q,
                ee_pose: Pose::from_isometry(&ur3_kin::fk(&ur3_kin::UR3, &q)),
                tile_pose: Pose { position: [-0.3, 0.1, 0.005], orientation: [0.0, 0.0, 0.0, 1.0] },
                row_poses: vec![],
                events: vec![],
                scene: vec![],
            })?;
        }
        let s = w.finish(&EpisodeSummary { success: true, ..Default::default() })?;
        bytes += s.bytes;
        messages += s.messages;
    }
    let write_s = t0.elapsed().as_secs_f64();
    let total_steps = episodes * steps;
    println!(
        "write: {total_steps} steps ({messages} messages, {:.1} MB) in {write_s:.3} s = {:.0} steps/s",
        bytes as f64 / 1e6,
        total_steps as f64 / write_s
    );

    // Load: best of 3 (the files are in the page cache after the first).
    let mut best = f64::INFINITY;
    let mut rows = 0;
    for _ in 0..3 {
        let t1 = Instant::now();
        let ds = load_dataset(&dir)?;
        best = best.min(t1.elapsed().as_secs_f64());
        rows = ds.rewards.len();
        assert_eq!(ds.obs.len(), rows * obs_dim);
    }
    println!("load: {episodes} episodes, {rows} rows x {obs_dim} obs into arrays in {best:.4} s (best of 3)");
    println!(
        "{{\"steps\": {total_steps}, \"write_s\": {write_s:.6}, \"steps_per_s\": {:.1}, \"load_s\": {best:.6}, \"bytes\": {bytes}, \"dir\": \"{}\"}}",
        total_steps as f64 / write_s,
        dir.display()
    );
    if !keep {
        std::fs::remove_dir_all(&dir)?;
    }
    Ok(())
}
