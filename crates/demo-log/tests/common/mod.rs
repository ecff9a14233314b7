//! Shared helpers: a deterministic demo built from simple formulas (no simulator).
#![allow(dead_code)]

use demo_log::*;
use std::path::{Path, PathBuf};
use ur3_kin::{HandLayout, Handedness, Space};

pub fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("demo-log-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

pub fn hand_header() -> HandLogHeader {
    let mut h = HandLogHeader::new(HandLayout::MediaPipe, Space::OpenXr, Handedness::Right);
    h.task = Some("suction".into());
    h.episode_seed = Some(7);
    h
}

pub fn hand_frame(i: usize, layout: HandLayout) -> HandFrame {
    let t = i as f64 / 30.0;
    HandFrame {
        t,
        tracked: i % 7 != 3,
        joints: (0..layout.joint_count())
            .map(|j| [0.1 * (t + j as f64).sin(), 1.2 + 0.01 * j as f64, -0.3 + 0.05 * (t * 0.5).cos()])
            .collect(),
        orientations: None,
    }
}

/// A scene entity at `position` (no rotation) in `frame_id`.
fn entity(
    id: &str,
    frame_id: &str,
    kind: Shape,
    size: [f64; 3],
    position: [f64; 3],
    color: [f32; 4],
) -> SceneEntity {
    let pose = Pose { position, orientation: [0.0, 0.0, 0.0, 1.0] };
    SceneEntity { id: id.into(), frame_id: frame_id.into(), kind, size, pose, color, extra: Vec::new() }
}

pub fn scene() -> Vec<SceneEntity> {
    vec![
        entity("table", "base", Shape::Cube, [0.8, 0.6, 0.02], [-0.3, 0.0, -0.01], [0.6, 0.5, 0.4, 1.0]),
        entity("tile", "tile", Shape::Cube, [0.1, 0.1, 0.01], [0.0; 3], [0.9, 0.9, 0.85, 1.0]),
        entity("target", "base", Shape::Cube, [0.1, 0.1, 0.001], [-0.3, 0.2, 0.0], [0.2, 0.8, 0.2, 0.5]),
        entity(
            "cup0",
            "tool0",
            Shape::Cylinder,
            [0.02, 0.02, 0.01],
            [0.02, 0.02, 0.005],
            [0.1, 0.1, 0.1, 1.0],
        ),
    ]
}

pub fn step(i: u64, n: u64, obs_dim: usize, act_dim: usize) -> StepRecord {
    let t = i as f64 * 0.04;
    let q = [0.1 * t, -1.2 + 0.05 * t, 1.0, -0.5, -1.57, 0.2 * t];
    let ee = ur3_kin::fk(&ur3_kin::UR3, &q);
    StepRecord {
        step: i,
        t,
        obs: (0..obs_dim).map(|k| ((i as usize * 31 + k) % 97) as f32 * 0.01 - 0.3).collect(),
        action: (0..act_dim).map(|k| ((i as usize + k) % 5) as f32 * 0.25 - 0.5).collect(),
        reward: if i == 10 || i + 1 == n { 1.0 } else { 0.0 },
        terminated: i + 1 == n,
        truncated: false,
        gesture: if (i / 15) % 2 == 0 { "hold".into() } else { "suction".into() },
        joints: q,
        ee_pose: Pose::from_isometry(&ee),
        tile_pose: Pose { position: [-0.3, 0.05 * t, 0.005], orientation: [0.0, 0.0, 0.0, 1.0] },
        row_poses: vec![],
        events: if i == 10 { vec!["pick".into()] } else { vec![] },
        scene: vec![],
    }
}

pub fn meta(episode: u64) -> EpisodeMeta {
    EpisodeMeta {
        episode,
        task: "suction".into(),
        seed: 42 + episode,
        robot_model: "ur3".into(),
        hand: Some(hand_header()),
        gesture_model: "svm-test".into(),
        control_dt: 0.04,
        scene: scene(),
        ..Default::default()
    }
}

/// Write a demo of `n` steps (each with one hand frame before it); returns its stats.
pub fn write_demo(
    path: &Path,
    episode: u64,
    n: u64,
    obs_dim: usize,
    act_dim: usize,
    opts: WriterOptions,
) -> WriteStats {
    let mut w = DemoWriter::create_with_options(path, &meta(episode), opts).unwrap();
    for i in 0..n {
        let s = step(i, n, obs_dim, act_dim);
        w.write_hand_frame(&hand_frame(i as usize, HandLayout::MediaPipe), s.t).unwrap();
        w.write_step(&s).unwrap();
    }
    w.finish(&EpisodeSummary { success: true, ..Default::default() }).unwrap()
}
