//! Task specs: the four built-in files parse, agree with the crate's constants and the named
//! start distributions, and a spec's numbers reach the episode; bad specs are refused with the
//! field, the value and why.

use tile_sim::spec::{EffectorSpec, TargetSpec};
use tile_sim::world;
use tile_sim::{
    Env, FALL_SPEED, FALL_Z, HOME_Q, INSTALL_DIST, MAX_EPISODE_STEPS, PICK_DIST, PLACE_DIST, SCREW_TURNS,
    SpecError, Task, TaskSpec, Variation,
};

const SUCTION: &str = include_str!("../tasks/tile_suction.toml");

#[test]
fn builtin_specs_parse_and_name_their_tasks() {
    for task in Task::ALL {
        let spec = task.spec();
        assert_eq!(spec.version, 1);
        assert_eq!(spec.name, task.name());
        assert_eq!(spec.task(), task);
        assert_eq!(spec.robot.model, "ur3");
        assert_eq!(spec.robot.home_q, HOME_Q);
        assert_eq!((spec.robot.joint_step, spec.joint_step()), (None, tile_sim::MAX_JOINT_STEP));
        assert_eq!((spec.rewards.pick, spec.rewards.success, spec.rewards.fail), (1.0, 1.0, -0.5));
        assert_eq!(spec.table.half_extents, world::TABLE_HALF);
        assert_eq!(spec.table.top_z, world::TABLE_TOP);
        assert_eq!(spec.table.friction, world::FRICTION);
        // The paper's three share the paper's episode length and starts; TileRow has its own
        // (tests/tile_row.rs) and is the only one with a row.
        if task == Task::TileRow {
            assert_eq!(spec.row.map(|r| r.count), Some(3));
        } else {
            assert_eq!(spec.row, None, "{task:?}");
            assert_eq!(spec.episode.max_steps, MAX_EPISODE_STEPS);
            assert_eq!(spec.starts.paper.variation(), Variation::default(), "{task:?}");
        }
        // The file on disk is the one compiled in.
        let file = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tasks").join(match task {
            Task::TileSuction => "tile_suction.toml",
            Task::BlockGrip => "block_grip.toml",
            Task::Screw => "screw.toml",
            Task::TileRow => "tile_row.toml",
            Task::TilePlace => "tile_place.toml",
        });
        assert_eq!(TaskSpec::from_file(&file).unwrap(), *spec);
        assert_eq!(std::fs::read_to_string(&file).unwrap(), TaskSpec::builtin_toml(task));
    }
    assert_eq!(Task::BlockGrip.spec().starts.wide.variation(), Variation::wide());
}

#[test]
fn builtin_specs_hold_the_constants_values() {
    let s = Task::TileSuction.spec();
    let t = &s.thresholds;
    assert_eq!(t.pick_dist, Some(PICK_DIST));
    assert_eq!(t.success_dist, Some(INSTALL_DIST));
    assert_eq!((t.fall_z, t.fall_speed), (Some(FALL_Z), Some(FALL_SPEED)));
    assert_eq!(t.fall_tilt_cos, Some(std::f32::consts::FRAC_1_SQRT_2));
    assert_eq!(s.object.half_extents, Some(world::TILE_HALF));
    assert_eq!((s.object.mass, s.object.friction), (Some(world::TILE_MASS), Some(world::FRICTION)));
    assert_eq!(
        s.effector,
        EffectorSpec::Suction {
            plate_half_extents: world::PLATE_HALF,
            cup_offset: world::CUP_OFFSET,
            cup_radius: world::CUP_RADIUS,
            tcp_z: world::CUP_TCP_Z,
            seal: None,
        }
    );
    assert_eq!(
        s.target,
        TargetSpec::Pad { xy: world::PAD_XY, half_extents: world::PAD_HALF, friction: world::FRICTION }
    );
    let [lo, hi] = s.starts.paper.object_x;
    assert_eq!(
        (lo, hi, s.starts.paper.object_y[0]),
        (world::OBJECT_X_MIN, world::OBJECT_X_MAX, world::OBJECT_Y)
    );

    let b = Task::BlockGrip.spec();
    assert_eq!(b.thresholds.success_dist, Some(PLACE_DIST));
    assert_eq!(b.thresholds.fall_speed, Some(2.0 * FALL_SPEED));
    assert_eq!(b.object.half_extents, Some([world::BLOCK_HALF; 3]));
    assert_eq!(b.object.mass, Some(world::BLOCK_MASS));
    let gripper = |spin_rate| EffectorSpec::Gripper {
        body_half_extents: world::GRIPPER_BODY_HALF,
        finger_half_extents: world::FINGER_HALF,
        finger_z: world::FINGER_Z,
        max_width: world::GRIP_MAX_WIDTH,
        speed: world::GRIP_SPEED,
        finger_friction: 1.0,
        spin_rate,
    };
    assert_eq!(b.effector, gripper(None));
    assert_eq!(b.tcp_z(), world::GRIP_TCP_Z);

    let n = Task::Screw.spec();
    assert_eq!(n.effector, gripper(Some(world::SPIN_RATE)));
    assert_eq!(
        (n.object.radius, n.object.half_height),
        (Some(world::NUT_RADIUS), Some(world::NUT_HALF_HEIGHT))
    );
    let TargetSpec::Bolt { plate_half_extents, radius, top_z, pitch, catch_gap, turns } = n.target else {
        panic!("the screw target is a bolt")
    };
    assert_eq!(plate_half_extents, [world::SCREW_PLATE_HALF, world::SCREW_PLATE_HALF, 0.005]);
    assert_eq!(
        (radius, top_z, pitch, turns),
        (world::BOLT_RADIUS, world::BOLT_TOP, world::THREAD_PITCH, SCREW_TURNS)
    );
    assert_eq!(top_z - world::NUT_HALF_HEIGHT - catch_gap, world::NUT_START_Z);
}

/// The built-in TileSuction text with `from` replaced by `to` (which must occur once).
fn edited(from: &str, to: &str) -> String {
    assert_eq!(SUCTION.matches(from).count(), 1, "{from:?} must occur once");
    SUCTION.replacen(from, to, 1)
}

fn invalid(text: &str) -> (String, String, String) {
    match TaskSpec::from_toml(text, "bad.toml") {
        Err(SpecError::Invalid { field, value, reason }) => (field, value, reason),
        other => panic!("expected an invalid field, got {other:?}"),
    }
}

fn parse_error(text: &str) -> String {
    match TaskSpec::from_toml(text, "bad.toml") {
        Err(e @ SpecError::Parse { .. }) => e.to_string(),
        other => panic!("expected a parse error, got {other:?}"),
    }
}

#[test]
fn bad_values_name_the_field_the_value_and_why() {
    let (f, v, why) = invalid(&edited("version = 1", "version = 2"));
    assert_eq!((f.as_str(), v.as_str()), ("version", "2"));
    assert!(why.contains("version 1"), "{why}");

    let (f, v, why) = invalid(&edited("mass = 0.5 ", "mass = -0.5 "));
    assert_eq!((f.as_str(), v.as_str()), ("object.mass", "-0.5"));
    assert!(why.contains("> 0"), "{why}");

    let (f, v, why) = invalid(&edited("model = \"ur3\"", "model = \"ur5\""));
    assert_eq!((f.as_str(), v.as_str()), ("robot.model", "\"ur5\""));
    assert!(why.contains("ur3, ur3e, ur5e, ur10e"), "{why}");

    for bad in ["0.0", "-1.5", "inf", "nan"] {
        let (f, v, why) =
            invalid(&edited("model = \"ur3\"\n", &format!("model = \"ur3\"\nhand_scale = {bad}\n")));
        assert_eq!(f, "robot.hand_scale", "{bad}: {v}");
        assert!(why.contains("> 0"), "{why}");
    }

    for bad in ["0.0", "-0.01", "inf", "nan"] {
        let (f, v, why) =
            invalid(&edited("model = \"ur3\"\n", &format!("model = \"ur3\"\njoint_step = {bad}\n")));
        assert_eq!(f, "robot.joint_step", "{bad}: {v}");
        assert!(why.contains("> 0"), "{why}");
    }
    // Above the arm's slowest rated joint speed × CONTROL_DT: the UR3's π rad/s gives 0.1257 rad
    // a step; the UR10e's shoulder (120°/s) 0.0838, so a step the UR3 takes is too fast there.
    let (f, v, why) = invalid(&edited("model = \"ur3\"\n", "model = \"ur3\"\njoint_step = 0.13\n"));
    assert_eq!((f.as_str(), v.as_str()), ("robot.joint_step", "0.13"));
    assert!(why.contains("at most 0.1257") && why.contains("ur3") && why.contains("rated"), "{why}");
    let fast = "model = \"ur3\"\njoint_step = 0.1\n";
    assert_eq!(TaskSpec::from_toml(&edited("model = \"ur3\"\n", fast), "t").unwrap().joint_step(), 0.1);
    let ur10e = edited("model = \"ur3\"\n", "model = \"ur10e\"\njoint_step = 0.1\n");
    let e = TaskSpec::from_toml(&ur10e, "t").unwrap_err();
    assert_eq!(e.field(), Some("robot.joint_step"), "{e}");
    assert!(e.to_string().contains("at most 0.0838"), "{e}");

    let (f, v, why) = invalid(&edited("pick_dist = 0.04 ", "# pick_dist = 0.04 "));
    assert_eq!((f.as_str(), v.as_str()), ("thresholds.pick_dist", "(missing)"));
    assert!(why.contains("suction logic needs it"), "{why}");

    let (f, _, why) = invalid(&edited("[thresholds]\n", "[thresholds]\nslip_dist = 0.01\n"));
    assert_eq!(f, "thresholds.slip_dist");
    assert!(why.contains("does not read it"), "{why}");

    let (f, v, _) = invalid(&edited("object_x = [0.0, 0.15]", "object_x = [0.15, 0.0]"));
    assert_eq!((f.as_str(), v.as_str()), ("starts.paper.object_x", "[0.15, 0.0]"));

    let (f, v, why) = invalid(&edited("target_jitter = 0.04", "target_jitter = 0.5"));
    assert_eq!((f.as_str(), v.as_str()), ("starts.wide.target_jitter", "0.5"));
    assert!(why.contains("[0, 0.04] m"), "{why}");

    let (f, v, why) = invalid(&edited("shape = \"box\"", "shape = \"sphere\""));
    assert_eq!((f.as_str(), v.as_str()), ("object.shape", "\"sphere\""));
    assert!(why.contains("box"), "{why}");

    let cylinder = "shape = \"cylinder\"\nradius = 0.05\nhalf_height = 0.005 #";
    let (f, v, why) = invalid(&edited("shape = \"box\"\nhalf_extents = [0.075, 0.075, 0.005] ", cylinder));
    assert_eq!((f.as_str(), v.as_str()), ("object.shape", "\"cylinder\""));
    assert!(why.contains("TileSuction logic moves a box"), "{why}");

    let (f, v, _) = invalid(&edited("max_steps = 750", "max_steps = 0"));
    assert_eq!((f.as_str(), v.as_str()), ("episode.max_steps", "0"));

    let (f, _, _) = invalid(&edited("friction = 0.6                        #", "friction = -1.0 #"));
    assert_eq!(f, "object.friction");

    let (f, v, why) = invalid(&edited("gestures = \"grip\"", "gestures = \"screw\""));
    assert_eq!((f.as_str(), v.as_str()), ("about.gestures", "\"screw\""));
    assert!(why.contains("TileSuction logic is driven by the \"grip\" gesture classes"), "{why}");

    let (f, v, why) = invalid(&edited("success = \"installed\"", "success = \" \""));
    assert_eq!((f.as_str(), v.as_str()), ("about.success", "\" \""));
    assert!(why.contains("line of text"), "{why}");

    let (f, _, _) = invalid(&edited("instruction = \"Pick", "instruction = \"\\nPick"));
    assert_eq!(f, "about.instruction");

    // a bigger tile on the built-in wide starts: some of them would touch the pad
    let (f, v, why) =
        invalid(&edited("half_extents = [0.075, 0.075, 0.005]", "half_extents = [0.1, 0.1, 0.006]"));
    assert_eq!(f, "starts.wide");
    assert!(v.contains("object (") && v.contains("yaw"), "{v}");
    assert!(why.contains("a start of this distribution is refused") && why.contains("of the pad"), "{why}");
    // and a wide box that leaves the reach
    let (f, _, why) = invalid(&edited("object_y = [0.26, 0.36]", "object_y = [0.26, 0.46]"));
    assert_eq!(f, "starts.wide");
    assert!(why.contains("out of reach"), "{why}");

    let e = TaskSpec::from_toml(&edited("version = 1", "version = 7"), "x.toml").unwrap_err();
    assert_eq!(e.field(), Some("version"));
    assert_eq!(e.to_string(), "version = 7: this simulator reads version 1");
}

#[test]
fn bad_structure_is_a_parse_error_with_the_place() {
    let m = parse_error(&edited("mass = 0.5 ", "masss = 0.5 "));
    assert!(m.starts_with("bad.toml: ") && m.contains("masss") && m.contains("line"), "{m}");
    // the place as fields: the line (1-based), the column, the line's text without its comment
    let text = edited("mass = 0.5 ", "masss = 0.5 ");
    let want_line = text.lines().position(|l| l.starts_with("masss")).unwrap() + 1;
    match TaskSpec::from_toml(&text, "bad.toml") {
        Err(SpecError::Parse { line, column, text, reason, .. }) => {
            assert_eq!((line, column, text.as_str()), (Some(want_line), Some(1), "masss = 0.5"));
            assert!(reason.starts_with("unknown field `masss`"), "{reason}");
        }
        other => panic!("expected a parse error, got {other:?}"),
    }
    let m = parse_error(&edited("mass = 0.5 ", "mass = \"heavy\" "));
    assert!(m.contains(&format!("line {want_line}, column 8 (mass = \"heavy\"): invalid type")), "{m}");
    let m = parse_error(&edited("pick = 1.0 ", "pick = \"one\" "));
    assert!(m.contains("pick") || m.contains("invalid type"), "{m}");
    let m = parse_error(&edited("[episode]", "[episode"));
    assert!(m.contains("line"), "{m}");
    // A bolt's fields are not a pad's.
    let m = parse_error(&edited("kind = \"pad\"", "kind = \"bolt\""));
    assert!(m.contains("unknown field `xy`") || m.contains("unknown field"), "{m}");
    let m = parse_error(&edited("kind = \"suction\"", "kind = \"magnet\""));
    assert!(m.contains("magnet"), "{m}");
    let m = parse_error(&edited("max_steps = 750", ""));
    assert!(m.contains("max_steps"), "{m}");
    let e = TaskSpec::from_file(std::path::Path::new("/nonexistent/task.toml")).unwrap_err();
    assert!(matches!(e, SpecError::Io { .. }), "{e}");
}

#[test]
fn a_specs_numbers_reach_the_episode() {
    // Rewards, episode length: a spec with its own numbers runs them.
    let text = edited("max_steps = 750", "max_steps = 12").replace("pick = 1.0 ", "pick = 2.5 ");
    let spec = std::sync::Arc::new(TaskSpec::from_toml(&text, "short.toml").unwrap());
    let mut env = Env::from_spec(spec, 0);
    assert_eq!(env.max_episode_steps(), 12);
    let mut obs = vec![0.0; Task::TileSuction.obs_dim()];
    env.reset(Some(4), &mut obs).unwrap();
    let mut steps = 0;
    loop {
        let o = env.step(&[0.0; 7], &mut obs).unwrap();
        steps += 1;
        if o.truncated {
            break;
        }
    }
    assert_eq!(steps, 12);
    // The spec's pick reward is paid: put the cups on the tile and switch suction on.
    let spec = env.spec().clone();
    let mut env = Env::from_spec(spec, 0);
    env.reset(Some(4), &mut obs).unwrap();
    let s = env.snapshot();
    let grasp = nalgebra::Vector3::new(s.object.t[0], s.object.t[1], s.object.t[2] + 0.005);
    let q = tile_sim::expert::ik_dls(&tile_sim::expert::tool0_for_tcp(grasp, 0.05), &s.q).unwrap();
    env.set_joints(q).unwrap();
    let o = env.step(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], &mut obs).unwrap();
    assert_eq!(o.reward, 2.5);

    // A bigger tile (its wide starts kept 2 cm further from the pad): the world and the scene
    // read the spec.
    let text = edited("half_extents = [0.075, 0.075, 0.005]", "half_extents = [0.08, 0.08, 0.006]").replacen(
        "object_x = [0.035, 0.285]",
        "object_x = [0.055, 0.285]",
        1,
    );
    let spec = std::sync::Arc::new(TaskSpec::from_toml(&text, "big.toml").unwrap());
    let mut env = Env::from_spec(spec, 0);
    env.reset(Some(4), &mut obs).unwrap();
    assert!((env.snapshot().object.t[2] - 0.006).abs() < 1e-6, "the tile rests on the table");
    let tile = env.scene().items.into_iter().find(|i| i.name == "tile").unwrap();
    assert_eq!(tile.shape, tile_sim::Shape::Box { half: [0.08, 0.08, 0.006] });
}

#[test]
fn a_vec_env_runs_its_specs_episode_length() {
    let text = edited("max_steps = 750", "max_steps = 8");
    let spec = std::sync::Arc::new(TaskSpec::from_toml(&text, "short.toml").unwrap());
    let mut v = tile_sim::VecEnv::from_spec(spec, 3, 5, 1).unwrap();
    let mut buf = tile_sim::StepBuffers::new(Task::TileSuction, 3);
    let actions = vec![0.0f32; 3 * 7];
    for k in 1..=8 {
        v.step_buffers(&actions, &mut buf).unwrap();
        assert_eq!(buf.truncated, vec![k == 8; 3], "step {k}");
        if k == 5 {
            // A checkpoint of a running episode restores (its actions replay within the length).
            let state = v.state();
            let mut obs = vec![0.0; 3 * Task::TileSuction.obs_dim()];
            v.restore(&state, &mut obs).unwrap();
            assert_eq!(obs, buf.obs);
        }
    }
}
