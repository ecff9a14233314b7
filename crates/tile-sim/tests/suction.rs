//! TileSuction: thresholds at their edges, fall, truncation, suction behaviour, home pose.

use nalgebra::Vector3;
use tile_sim::expert::{ik_dls, tool0_for_tcp};
use tile_sim::world::{CUP_TCP_Z, PAD_HALF, PAD_XY, TILE_HALF};
use tile_sim::{Env, HOME_Q, MAX_EPISODE_STEPS, SimError, Task};

const T: Task = Task::TileSuction;

fn obs() -> Vec<f32> {
    vec![0.0; T.obs_dim()]
}

/// Put the cup centre at `tcp` (flange down) by teleporting the arm.
fn place_cups(env: &mut Env, tcp: [f64; 3]) {
    let s = env.snapshot();
    let goal = tool0_for_tcp(Vector3::new(tcp[0], tcp[1], tcp[2]), CUP_TCP_Z as f64);
    let q = ik_dls(&goal, &s.q).expect("reachable cup pose");
    env.set_joints(q).expect("set joints");
    let c = env.snapshot().tcp.t;
    assert!((0..3).all(|i| (c[i] - tcp[i]).abs() < 1e-5), "cup centre {c:?} != {tcp:?}");
}

fn iso(p: &tile_sim::PoseRec) -> nalgebra::Isometry3<f64> {
    nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(p.t[0], p.t[1], p.t[2]),
        nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(p.q[3], p.q[0], p.q[1], p.q[2])),
    )
}

fn act(cmd: f32) -> [f32; 7] {
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, cmd]
}

fn grasp_point(env: &Env) -> [f64; 3] {
    let o = env.snapshot().object.t;
    [o[0], o[1], o[2] + TILE_HALF[2] as f64]
}

fn pick_at_distance(d: f64, seed: u64) -> (tile_sim::StepOutcome, Env) {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(seed), &mut o).unwrap();
    let g = grasp_point(&env);
    place_cups(&mut env, [g[0], g[1], g[2] + d]);
    let out = env.step(&act(1.0), &mut o).unwrap();
    (out, env)
}

#[test]
fn pick_threshold_edges() {
    for seed in [1, 2, 3] {
        let (near, env) = pick_at_distance(0.03, seed);
        assert_eq!(near.reward, 1.0, "pick at 0.03 m pays +1");
        assert!(near.picked && near.held);
        assert!(env.snapshot().held);
        let (far, env) = pick_at_distance(0.05, seed);
        assert_eq!(far.reward, 0.0, "no pick at 0.05 m");
        assert!(!far.picked && !far.held && !env.snapshot().held);
        // Just inside / just outside the 0.04 m threshold.
        assert!(pick_at_distance(0.0395, seed).0.held);
        assert!(!pick_at_distance(0.0405, seed).0.held);
    }
}

#[test]
fn pick_needs_suction_command_and_pays_once() {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(5), &mut o).unwrap();
    let g = grasp_point(&env);
    place_cups(&mut env, [g[0], g[1], g[2] + 0.01]);
    // Fixed (0) with suction off: nothing.
    let r = env.step(&act(0.0), &mut o).unwrap();
    assert_eq!(r.reward, 0.0);
    assert!(!r.held);
    // Observation: ee_state −1 (off), newest frame last.
    let f = &o[4 * 16..];
    assert_eq!(f[6], -1.0);
    let r = env.step(&act(1.0), &mut o).unwrap();
    assert_eq!(r.reward, 1.0);
    assert_eq!(o[4 * 16 + 6], 1.0);
    // Fixed holds the suction state and the tile; no second reward.
    for _ in 0..5 {
        let r = env.step(&act(0.0), &mut o).unwrap();
        assert_eq!(r.reward, 0.0);
        assert!(r.held && r.picked);
    }
    // Drop releases; re-suction of the same tile pays nothing more.
    let r = env.step(&act(-1.0), &mut o).unwrap();
    assert!(!r.held && r.picked);
    assert_eq!(o[4 * 16 + 6], -1.0);
    let r = env.step(&act(1.0), &mut o).unwrap();
    assert!(r.held);
    assert_eq!(r.reward, 0.0);
}

#[test]
fn held_tile_follows_the_cups() {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(9), &mut o).unwrap();
    let g = grasp_point(&env);
    place_cups(&mut env, [g[0], g[1], g[2] + 0.005]);
    env.step(&act(1.0), &mut o).unwrap();
    let s0 = env.snapshot();
    let off0 = iso(&s0.tool0).inverse() * iso(&s0.object);
    // Move the shoulder lift joint for 20 steps: tile keeps its offset to the cups.
    let mut a = act(0.0);
    a[1] = -1.0;
    for _ in 0..20 {
        let r = env.step(&a, &mut o).unwrap();
        assert!(r.held && !r.fell);
    }
    let s1 = env.snapshot();
    assert!(s1.object.t[2] > s0.object.t[2] + 0.05, "lifted");
    // Constant offset in the flange frame (f32 physics: within 0.1 mm / 1 mrad).
    let off1 = iso(&s1.tool0).inverse() * iso(&s1.object);
    assert!((off1.translation.vector - off0.translation.vector).norm() < 1e-4);
    assert!(off1.rotation.angle_to(&off0.rotation) < 1e-3);
}

fn tile_on_pad(dx: f64) -> tile_sim::StepOutcome {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(11), &mut o).unwrap();
    let target = env.snapshot().target.t;
    let z = 2.0 * PAD_HALF[2] as f64 + TILE_HALF[2] as f64;
    assert!((target[2] - z).abs() < 1e-6);
    assert!((target[0] - PAD_XY[0] as f64).abs() < 1e-6);
    env.set_object_pose([target[0] + dx, target[1], z], [0.0, 0.0, 0.0, 1.0]).unwrap();
    let out = env.step(&act(0.0), &mut o).unwrap();
    let s = env.snapshot();
    let d = ((s.object.t[0] - target[0]).powi(2)
        + (s.object.t[1] - target[1]).powi(2)
        + (s.object.t[2] - target[2]).powi(2))
    .sqrt();
    assert!((d - dx).abs() < 5e-4, "tile settled at {d} instead of {dx}");
    out
}

#[test]
fn install_threshold_edges() {
    let ok = tile_on_pad(0.029);
    assert!(ok.installed && ok.terminated && !ok.truncated);
    assert_eq!(ok.reward, 1.0);
    let no = tile_on_pad(0.031);
    assert!(!no.installed && !no.terminated);
    assert_eq!(no.reward, 0.0);
}

#[test]
fn install_while_held_counts() {
    // Paper reading: carrying the tile within 0.03 m of the target finishes the task.
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(4), &mut o).unwrap();
    let g = grasp_point(&env);
    place_cups(&mut env, [g[0], g[1], g[2] + 0.005]);
    assert_eq!(env.step(&act(1.0), &mut o).unwrap().reward, 1.0);
    let t = env.snapshot().target.t;
    // Cups 0.02 m above where they'd be with the tile on the target: tile 0.02 m above target.
    place_cups(&mut env, [t[0], t[1], t[2] + TILE_HALF[2] as f64 + 0.005 + 0.02]);
    let r = env.step(&act(0.0), &mut o).unwrap();
    assert!(r.held && r.installed && r.terminated);
    assert_eq!(r.reward, 1.0);
    assert_eq!(env.step(&act(0.0), &mut o), Err(SimError::EpisodeOver));
}

#[test]
fn tile_off_the_table_falls() {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(3), &mut o).unwrap();
    env.set_object_pose([0.8, 0.3, 0.05], [0.0, 0.0, 0.0, 1.0]).unwrap();
    let mut total = 0.0;
    for k in 0..100 {
        let r = env.step(&act(0.0), &mut o).unwrap();
        total += r.reward;
        if r.terminated {
            assert!(r.fell && !r.installed);
            assert_eq!(r.reward, -0.5);
            assert!(k < 30);
            break;
        }
        assert!(k < 99, "never fell");
    }
    assert_eq!(total, -0.5);
}

#[test]
fn tile_knocked_on_edge_falls() {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(3), &mut o).unwrap();
    // Standing on its edge (rotated 60° about x): tilted past 45°.
    let a = 60f64.to_radians() / 2.0;
    env.set_object_pose([0.1, 0.35, 0.08], [a.sin(), 0.0, 0.0, a.cos()]).unwrap();
    let r = env.step(&act(0.0), &mut o).unwrap();
    assert!(r.fell && r.terminated);
    assert_eq!(r.reward, -0.5);
}

#[test]
fn dropped_tile_falls_but_set_down_does_not() {
    for (height, falls) in [(0.15, true), (0.002, false)] {
        let mut env = Env::new(T, 0);
        let mut o = obs();
        env.reset(Some(8), &mut o).unwrap();
        let g = grasp_point(&env);
        place_cups(&mut env, [g[0], g[1], g[2] + 0.002]);
        env.step(&act(1.0), &mut o).unwrap();
        place_cups(&mut env, [g[0], g[1], g[2] + 0.002 + height]);
        let mut fell = false;
        let mut r = env.step(&act(-1.0), &mut o).unwrap();
        for _ in 0..40 {
            fell |= r.fell;
            if r.terminated {
                break;
            }
            r = env.step(&act(0.0), &mut o).unwrap();
        }
        assert_eq!(fell, falls, "drop from {height} m");
    }
}

#[test]
fn truncation_at_750() {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(1), &mut o).unwrap();
    for k in 1..=MAX_EPISODE_STEPS {
        let r = env.step(&act(0.0), &mut o).unwrap();
        assert!(!r.terminated);
        assert_eq!(r.truncated, k == MAX_EPISODE_STEPS, "step {k}");
        assert_eq!(r.reward, 0.0);
    }
    assert_eq!(env.snapshot().step, 750);
    assert_eq!(env.step(&act(0.0), &mut o), Err(SimError::EpisodeOver));
    env.reset(None, &mut o).unwrap();
    assert!(env.step(&act(0.0), &mut o).is_ok());
}

#[test]
fn home_pose_and_layout() {
    let t = ur3_kin::fk(&ur3_kin::UR3, &HOME_Q);
    // Flange pointing down, cup centre 0.2 m above the table at (0.05, 0.25).
    let z = t.rotation * Vector3::z();
    assert!((z - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-6);
    let p = t.translation.vector;
    assert!((p - Vector3::new(0.05, 0.25, 0.25)).norm() < 1e-6);
    let mut env = Env::new(T, 0);
    let mut o = obs();
    for seed in 0..200 {
        env.reset(Some(seed), &mut o).unwrap();
        let s = env.snapshot();
        assert!((0.0..=0.15).contains(&s.object.t[0]), "tile x in [0, 0.15]");
        assert!((s.object.t[2] - TILE_HALF[2] as f64).abs() < 1e-6);
        // Frames: 4 zero frames, then [q, -1, cup, target, tile].
        assert!(o[..64].iter().all(|&v| v == 0.0));
        let f = &o[64..];
        for i in 0..6 {
            assert_eq!(f[i], HOME_Q[i] as f32);
        }
        assert_eq!(f[6], -1.0);
        assert_eq!(&f[7..10], &[s.tcp.t[0] as f32, s.tcp.t[1] as f32, s.tcp.t[2] as f32]);
        assert_eq!(&f[10..13], &[s.target.t[0] as f32, s.target.t[1] as f32, s.target.t[2] as f32]);
        assert_eq!(&f[13..16], &[s.object.t[0] as f32, s.object.t[1] as f32, s.object.t[2] as f32]);
    }
}

#[test]
fn frame_stacking_newest_last() {
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(2), &mut o).unwrap();
    let mut frames: Vec<Vec<f32>> = vec![o[64..].to_vec()];
    let mut a = act(0.0);
    a[0] = 1.0;
    for k in 1..=6 {
        env.step(&a, &mut o).unwrap();
        frames.push(o[64..].to_vec());
        let zero = 4usize.saturating_sub(k);
        assert!(o[..zero * 16].iter().all(|&v| v == 0.0), "{zero} zero frames after {k} steps");
        for j in 0..(5 - zero) {
            let expect = &frames[frames.len() - 1 - j];
            assert_eq!(&o[(4 - j) * 16..(5 - j) * 16], expect.as_slice());
        }
        // q0 moved by exactly MAX_JOINT_STEP per step.
        let q0 = HOME_Q[0] + k as f64 * tile_sim::MAX_JOINT_STEP;
        assert!((o[64] as f64 - q0).abs() < 1e-6);
    }
}
