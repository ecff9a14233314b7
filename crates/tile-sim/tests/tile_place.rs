//! TilePlace: the contact hold (a seal per cup, force limits, a held tile that still collides)
//! and the placed rule, through the env.

use nalgebra::Vector3;
use std::sync::Arc;
use tile_sim::expert::{Expert, ik_dls, tool0_for_tcp};
use tile_sim::{Env, StepOutcome, Task, TaskSpec};

const T: Task = Task::TilePlace;
const TILE_HALF_Z: f64 = 0.005;
const TCP_Z: f64 = 0.05;

fn obs() -> Vec<f32> {
    vec![0.0; T.obs_dim()]
}

fn act(dq: [f32; 6], cmd: f32) -> [f32; 7] {
    [dq[0], dq[1], dq[2], dq[3], dq[4], dq[5], cmd]
}

/// The built-in spec with `[effector.seal]`'s `vacuum_kpa` set to `kpa`.
fn with_vacuum(kpa: f32) -> Arc<TaskSpec> {
    let text = TaskSpec::builtin_toml(T).replace("vacuum_kpa = 60.0", &format!("vacuum_kpa = {kpa}"));
    Arc::new(TaskSpec::from_toml(&text, "weak.toml").unwrap())
}

/// Teleport the arm so the cup centre is at `tcp` (flange down).
fn place_cups(env: &mut Env, tcp: [f64; 3]) {
    let q = ik_dls(&tool0_for_tcp(Vector3::from(tcp), TCP_Z), &env.snapshot().q).expect("reachable");
    env.set_joints(q).unwrap();
}

/// The action that moves the cup centre by `d` (m) in one step (as far as a step goes).
fn move_cups(env: &Env, d: [f64; 3]) -> [f32; 6] {
    let s = env.snapshot();
    let goal = Vector3::from(s.tcp.t) + Vector3::from(d);
    let tool0 = nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::from(goal - iso_rot(&s.tool0) * Vector3::new(0.0, 0.0, TCP_Z)),
        iso_rot(&s.tool0),
    );
    let q = ik_dls(&tool0, &s.q).expect("reachable");
    env.action_toward(&q).map(|v| v as f32)
}

/// The action (TilePlace commands the tool) that turns the base by `share` of a joint step.
fn turn_base(env: &Env, share: f64) -> [f32; 6] {
    let mut q = env.snapshot().q;
    q[0] += share * env.joint_step();
    env.action_toward(&q).map(|v| v as f32)
}

fn iso_rot(p: &tile_sim::PoseRec) -> nalgebra::UnitQuaternion<f64> {
    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(p.q[3], p.q[0], p.q[1], p.q[2]))
}

/// An env on episode `seed` with the cups on the tile's face (1 mm above it), suction on and
/// the vacuum built up (5 steps).
fn holding(spec: Arc<TaskSpec>, seed: u64) -> Env {
    let mut env = Env::from_spec(spec, 0);
    let mut o = obs();
    env.reset(Some(seed), &mut o).unwrap();
    for _ in 0..10 {
        env.step(&act([0.0; 6], 0.0), &mut o).unwrap(); // the tile settles on the table
    }
    let t = env.snapshot().object.t;
    place_cups(&mut env, [t[0], t[1], t[2] + TILE_HALF_Z + 0.001]);
    for _ in 0..5 {
        let out = env.step(&act([0.0; 6], 1.0), &mut o).unwrap();
        assert!(out.held, "the cups on the face hold the tile");
    }
    env
}

/// Run the scripted expert on episode `seed`: the last step's outcome, the steps, the env.
fn expert_episode(seed: u64, wide: bool) -> (StepOutcome, u32, Env) {
    let mut env = Env::new(T, 0);
    if wide {
        env.set_variation(T.spec().starts.wide.variation()).unwrap();
    }
    let mut o = obs();
    env.reset(Some(seed), &mut o).unwrap();
    let mut ex = Expert::new(T);
    let mut a = [0.0f32; 7];
    for k in 1..=750 {
        ex.act(&env.snapshot(), &mut a);
        let out = env.step(&a, &mut o).unwrap();
        if out.terminated || out.truncated {
            return (out, k, env);
        }
    }
    unreachable!("an episode ends by its 750th step")
}

#[test]
fn the_expert_places_the_tile_square_on_the_paper_and_wide_starts() {
    let mut turned = 0;
    for (wide, seeds) in [(false, 0..10u64), (true, 100..120)] {
        for seed in seeds {
            let (out, k, env) = expert_episode(seed, wide);
            let pad_yaw = env.start().pad_yaw.to_degrees();
            assert!(pad_yaw.abs() <= 15.0 && (wide || pad_yaw == 0.0), "pad turned {pad_yaw} deg");
            turned += usize::from(pad_yaw.abs() > 5.0);
            let p = env.last_placement().expect("a tile task reports its placement").clone();
            assert!(out.installed && !out.fell, "seed {seed} (wide {wide}): not placed in {k} steps: {p:?}");
            assert!(!p.held && p.xy_error < 0.005 && p.yaw_error_deg.abs() < 2.0, "{p:?}");
            assert!(p.height_above_rest.abs() < 0.002, "{p:?}");
            assert_eq!(p.hold_gaps.len(), 1);
            assert!(p.hold_gaps[0].abs() <= 0.003, "the lips were on the face: {p:?}");
        }
    }
    assert!(turned >= 5, "the wide starts turn the pad: {turned} of 20 by more than 5 deg");
}

#[test]
fn suction_on_with_the_lips_10_mm_above_the_face_takes_nothing() {
    for seed in [1, 2, 3] {
        let mut env = Env::new(T, 0);
        let mut o = obs();
        env.reset(Some(seed), &mut o).unwrap();
        let t0 = env.snapshot().object.t;
        place_cups(&mut env, [t0[0], t0[1], t0[2] + TILE_HALF_Z + 0.010]);
        for _ in 0..20 {
            let out = env.step(&act([0.0; 6], 1.0), &mut o).unwrap();
            assert!(!out.held && !out.picked && out.reward == 0.0, "seed {seed}: held from 10 mm");
        }
        assert_eq!(o[o.len() - T.obs_frame_dim() + 16], 0.0, "the vacuum switch reads nothing");
        let t = env.snapshot().object.t;
        assert!((t[2] - t0[2]).abs() < 0.002, "the tile was not pulled up: {t:?} vs {t0:?}");
        // 2 mm above the face, the lips seal: held, +1 once.
        place_cups(&mut env, [t[0], t[1], t[2] + TILE_HALF_Z + 0.002]);
        let out = env.step(&act([0.0; 6], 1.0), &mut o).unwrap();
        assert!(out.held && out.picked && out.reward == 1.0, "seed {seed}: no hold at 2 mm");
    }
}

/// The built-in spec with rigid cups (`[effector.seal]`'s `stroke` 0): they give only `gap`.
fn rigid_cups() -> Arc<TaskSpec> {
    let text = TaskSpec::builtin_toml(T).replace("stroke = 0.010", "stroke = 0.0");
    assert_ne!(text, TaskSpec::builtin_toml(T), "the built-in spec sets the cups' stroke");
    Arc::new(TaskSpec::from_toml(&text, "rigid.toml").unwrap())
}

#[test]
fn a_held_tile_lifts_with_the_cups_and_lands_on_the_table_not_through_it() {
    // (spec, how far the cups give below the face before the arm stops: gap + stroke)
    for (spec, give) in [(T.spec(), 0.003 + 0.010), (rigid_cups(), 0.003)] {
        let mut env = holding(spec, 4);
        let mut o = obs();
        let rest = TILE_HALF_Z; // the centre of a tile lying on the table
        for _ in 0..10 {
            let out = env.step(&act(move_cups(&env, [0.0, 0.0, 0.004]), 0.0), &mut o).unwrap();
            assert!(out.held);
        }
        let lifted = env.snapshot().object.t[2];
        assert!(lifted > rest + 0.03, "lifted 4 cm: {lifted} from {rest}");
        // Down at 2 mm a step, into the table where the tile rests on it: the
        // table stops the tile, the cups give up to gap + stroke (their lips stay sealed on
        // the face), and then the arm is stopped as a real one stops on its force limit (the
        // episode fails).
        let mut lowest = f64::INFINITY;
        let mut end = None;
        for k in 0..40 {
            let out = env.step(&act(move_cups(&env, [0.0, 0.0, -0.002]), 0.0), &mut o).unwrap();
            lowest = lowest.min(env.snapshot().object.t[2]);
            if out.terminated {
                end = Some((k, out));
                break;
            }
            let pressed = rest + TILE_HALF_Z - env.snapshot().tcp.t[2];
            assert!(out.held, "give {give}: the lips stay sealed pressed {pressed} m into the face");
        }
        let (k, out) = end.expect("pressing the tile into the table stops the arm");
        assert!(out.fell && out.reward == -0.5, "a protective stop is a failure: {out:?}");
        let s = env.snapshot();
        let pressed = rest + TILE_HALF_Z - s.tcp.t[2];
        assert!(
            pressed > give && pressed < give + 0.006,
            "give {give}: stopped at step {k} with the cups {pressed} m below the face at rest"
        );
        // Rapier's contacts are soft: pressed, the tile sinks a little into the table (measured
        // 1.6-2.7 mm at the stop), where a held kinematic tile would have followed the cups down.
        assert!(lowest > rest - 0.003, "give {give}: the tile went into the table: {lowest} vs {rest}");
    }
}

#[test]
fn a_weak_hold_keeps_a_gently_carried_tile_and_drops_a_hard_swung_one() {
    // 4 kPa: 4 cups hold 7.5 N along their axis, 3.8 N across (the tile weighs 4.9 N).
    let spec = with_vacuum(4.0);
    let mut o = obs();
    // Gently: lift 5 cm slowly, then turn the base at 0.1 of full speed one way and back.
    let mut env = holding(spec.clone(), 5);
    for _ in 0..25 {
        env.step(&act(move_cups(&env, [0.0, 0.0, 0.002]), 0.0), &mut o).unwrap();
    }
    for k in 0..40 {
        let dir = if k < 20 { 0.1 } else { -0.1 };
        let out = env.step(&act(turn_base(&env, dir), 0.0), &mut o).unwrap();
        assert!(out.held && !out.fell, "step {k}: a gentle carry lost the tile");
    }
    // Hard: the same at full speed, reversing every 5 steps.
    let mut env = holding(spec, 5);
    for _ in 0..25 {
        env.step(&act(move_cups(&env, [0.0, 0.0, 0.002]), 0.0), &mut o).unwrap();
    }
    let mut lost = None;
    for k in 0..60 {
        let dir = if (k / 5) % 2 == 0 { 1.0 } else { -1.0 };
        let out = env.step(&act(turn_base(&env, dir), 0.0), &mut o).unwrap();
        if !out.held {
            lost = Some(k);
            break;
        }
    }
    assert!(lost.is_some(), "a hard swing kept a tile the cups hold by 3.8 N across");
    // The built-in vacuum (60 kPa) holds the same swing.
    let mut env = holding(T.spec(), 5);
    for _ in 0..25 {
        env.step(&act(move_cups(&env, [0.0, 0.0, 0.002]), 0.0), &mut o).unwrap();
    }
    for k in 0..60 {
        let dir = if (k / 5) % 2 == 0 { 1.0 } else { -1.0 };
        let out = env.step(&act(turn_base(&env, dir), 0.0), &mut o).unwrap();
        assert!(out.held, "step {k}: the full vacuum lost the tile");
    }
}

#[test]
fn the_placed_rule_needs_the_seal_and_a_suction_head_without_a_row() {
    let text = TaskSpec::builtin_toml(T);
    let start = text.find("\n[effector.seal]\n").unwrap() + 1;
    let end = text[start..].find("\n[object]\n").unwrap() + start + 1;
    let no_seal = format!("{}{}", &text[..start], &text[end..]);
    let e = TaskSpec::from_toml(&no_seal, "no_seal.toml").unwrap_err();
    assert_eq!(e.field(), Some("effector.seal"), "{e}");
    assert!(e.to_string().contains("holds a tile by its sealed cups"), "{e}");
    // The row's spec with the placed rule: refused, not built yet.
    let row =
        TaskSpec::builtin_toml(Task::TileRow).replace("[thresholds]", "[thresholds]\nrule = \"placed\"");
    let e = TaskSpec::from_toml(&row, "row.toml").unwrap_err();
    assert_eq!(e.field(), Some("thresholds.rule"), "{e}");
    // BlockGrip's spec with the placed rule: refused, the suction head only.
    let grip =
        TaskSpec::builtin_toml(Task::BlockGrip).replace("[thresholds]", "[thresholds]\nrule = \"placed\"");
    let e = TaskSpec::from_toml(&grip, "grip.toml").unwrap_err();
    assert_eq!(e.field(), Some("thresholds.rule"), "{e}");
    assert!(e.to_string().contains("suction head only"), "{e}");
    // The paper's rule written out is today's TileSuction.
    let paper =
        TaskSpec::builtin_toml(Task::TileSuction).replace("[thresholds]", "[thresholds]\nrule = \"paper\"");
    assert_eq!(TaskSpec::from_toml(&paper, "paper.toml").unwrap().task(), Task::TileSuction);
}

#[test]
fn the_tcp_crossing_a_safety_plane_is_a_protective_stop() {
    let [lo, hi] = T.spec().robot.tcp_box.expect("TilePlace's cell has safety planes");
    // Straight up at a centimetre a step from the home pose: the episode ends, failed, in the
    // step the TCP crossed the top plane.
    let mut env = Env::new(T, 0);
    let mut o = obs();
    env.reset(Some(7), &mut o).unwrap();
    let mut end = None;
    for k in 0..100 {
        let z = env.snapshot().tcp.t[2];
        let out = env.step(&act(move_cups(&env, [0.0, 0.0, 0.01]), 0.0), &mut o).unwrap();
        if out.terminated {
            end = Some((k, z, out));
            break;
        }
    }
    let (k, before, out) = end.expect("the TCP went up to the plane");
    let after = env.snapshot().tcp.t[2];
    assert!(out.fell && out.reward == -0.5 && !out.installed, "a protective stop fails: {out:?}");
    assert!(before <= hi[2] && after > hi[2], "step {k}: {before} -> {after}, plane at {}", hi[2]);
    // Without the planes the same motion runs on.
    let text = TaskSpec::builtin_toml(T);
    let line = text.lines().find(|l| l.starts_with("tcp_box")).expect("the spec's line").to_string();
    let spec = Arc::new(TaskSpec::from_toml(&text.replace(&line, ""), "open.toml").unwrap());
    let mut env = Env::from_spec(spec, 0);
    env.reset(Some(7), &mut o).unwrap();
    for _ in 0..=k {
        let out = env.step(&act(move_cups(&env, [0.0, 0.0, 0.01]), 0.0), &mut o).unwrap();
        assert!(!out.terminated, "no planes, no stop");
    }
    assert!(env.snapshot().tcp.t[2] > hi[2] && lo[2] < 0.0);
}
