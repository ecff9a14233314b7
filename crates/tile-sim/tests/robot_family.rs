//! The robot family in the simulator: the arm per model (capsules from the DH table, joint
//! limits), TileSuction on a UR5e and a UR10e (`tasks/tile_suction_ur5e.toml`, `..._ur10e.toml`)
//! and the scripted expert installing the tile on each.

use std::sync::Arc;
use tile_sim::expert::Expert;
use tile_sim::{Env, StepOutcome, TaskSpec};

fn spec_file(name: &str) -> Arc<TaskSpec> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tasks").join(name);
    Arc::new(TaskSpec::from_file(&path).unwrap_or_else(|e| panic!("{name}: {e}")))
}

#[test]
fn ur3_capsules_are_the_simulators_numbers_since_the_first_version() {
    let (a2, a3, d4, d5, d6) = (0.24365f32, 0.21325f32, 0.11235f32, 0.08535f32, 0.0819f32);
    let want: Vec<(u8, [f32; 3], [f32; 3], f32)> = vec![
        (1, [0.0, -0.06, 0.0], [0.0, 0.0, 0.0], 0.06),
        (1, [0.0, 0.0, 0.0], [0.0, 0.0, 0.12], 0.055),
        (2, [a2, 0.0, 0.12], [0.0, 0.0, 0.12], 0.045),
        (2, [0.0, 0.0, 0.12], [0.0, 0.0, 0.027], 0.045),
        (3, [a3, 0.0, 0.027], [0.0, 0.0, 0.027], 0.035),
        (3, [0.0, 0.0, 0.027], [0.0, 0.0, d4], 0.035),
        (4, [0.0, 0.0, 0.0], [0.0, 0.0, d5], 0.035),
        (5, [0.0, 0.0, 0.0], [0.0, 0.0, d6 - 0.032], 0.032),
    ];
    assert_eq!(tile_sim::arm::capsules(&ur3_kin::UR3), want);
    assert_eq!(tile_sim::world::arm_capsules(), want);
}

#[test]
fn every_simulated_model_has_capsules_from_its_own_dh_table() {
    for d in &tile_sim::arm::SIMULATED {
        let m = ur3_kin::UrModel::by_name(d.model).unwrap();
        let c = tile_sim::arm::capsules(m);
        assert_eq!(c.len(), 8);
        assert_eq!(c[2].1[0], -m.a2 as f32, "{}: the upper arm spans a2", m.name);
        assert_eq!(c[4].1[0], -m.a3 as f32, "{}: the forearm spans a3", m.name);
        // the wrist-3 capsule's cap ends at the flange
        assert!((c[7].2[2] + c[7].3 - m.d6 as f32).abs() < 1e-6, "{}", m.name);
        assert!(c.iter().all(|(_, _, _, r)| *r > 0.0 && *r < 0.1));
        // the expert's joint speed stays within every joint's rated speed
        let lim = m.joint_limits();
        let speed = tile_sim::MAX_JOINT_STEP / f64::from(tile_sim::CONTROL_DT);
        assert!(lim.velocity.iter().all(|v| speed <= *v), "{}: {speed} rad/s", m.name);
    }
}

#[test]
fn the_family_specs_pass_the_check_and_name_their_arm() {
    for (file, model) in [("tile_suction_ur5e.toml", "ur5e"), ("tile_suction_ur10e.toml", "ur10e")] {
        let spec = spec_file(file);
        assert_eq!(spec.arm().name, model);
        let env = Env::from_spec(spec.clone(), 0);
        assert_eq!(env.arm().name, model);
        let names: Vec<&str> = env.scene().items.iter().map(|i| i.name).collect();
        assert!(names.contains(&format!("{model}_base").as_str()), "{names:?}");
    }
}

#[test]
fn the_hand_scale_is_the_arms_workspace_scale_unless_the_spec_sets_one() {
    let len = |m: &ur3_kin::UrModel| (m.a2.abs() + m.a3.abs()) as f32;
    for task in tile_sim::Task::ALL {
        assert_eq!(task.spec().hand_scale(), 1.0, "{task:?}: the built-in UR3 tasks stay at 1");
    }
    for (file, model) in
        [("tile_suction_ur5e.toml", &ur3_kin::UR5E), ("tile_suction_ur10e.toml", &ur3_kin::UR10E)]
    {
        let spec = spec_file(file);
        let k = len(model) / len(&ur3_kin::UR3);
        assert_eq!(spec.hand_scale(), tile_sim::workspace_scale(model), "{file}");
        assert!((spec.hand_scale() - k).abs() < 1e-6, "{file}: {} vs {k}", spec.hand_scale());
    }
    // UR5e 0.8172 / 0.4569 m, UR10e 1.18425 / 0.4569 m
    assert!((spec_file("tile_suction_ur5e.toml").hand_scale() - 1.789).abs() < 1e-3);
    assert!((spec_file("tile_suction_ur10e.toml").hand_scale() - 2.592).abs() < 1e-3);
    assert_eq!(tile_sim::workspace_scale(&ur3_kin::UR3E), 1.0);
    // an explicit robot.hand_scale wins over the arm's
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tasks/tile_suction_ur10e.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let set = text.replacen("model = \"ur10e\"\n", "model = \"ur10e\"\nhand_scale = 2.2\n", 1);
    assert_ne!(set, text);
    let spec = TaskSpec::from_toml(&set, "ur10e_2.2.toml").unwrap();
    assert_eq!(spec.hand_scale(), 2.2);
}

#[test]
fn a_full_action_moves_each_joint_by_the_specs_joint_step() {
    let builtin = tile_sim::Task::TileSuction.spec();
    let own = TaskSpec::builtin_toml(tile_sim::Task::TileSuction).replacen(
        "model = \"ur3\"\n",
        "model = \"ur3\"\njoint_step = 0.03\n",
        1,
    );
    let cases = [
        (builtin, tile_sim::MAX_JOINT_STEP),
        (Arc::new(TaskSpec::from_toml(&own, "own.toml").unwrap()), 0.03),
        (spec_file("tile_suction_ur5e.toml"), 0.025),
        (spec_file("tile_suction_ur10e.toml"), 0.018),
    ];
    for (spec, step) in cases {
        assert_eq!(spec.joint_step(), step, "{}", spec.name);
        let task = spec.task();
        let mut env = Env::from_spec(spec.clone(), 0);
        assert_eq!(env.joint_step(), step);
        let mut o = vec![0.0; task.obs_dim()];
        env.reset(Some(0), &mut o).unwrap();
        let q0 = env.snapshot().q;
        // full actions both ways, a half one, a clipped one, none
        let a = [1.0, -1.0, 0.5, 3.0, 0.0, -1.0, 0.0];
        env.step(&a, &mut o).unwrap();
        let q1 = env.snapshot().q;
        let want = [step, -step, 0.5 * step, step, 0.0, -step];
        for i in 0..6 {
            assert_eq!(q1[i], q0[i] + want[i], "{}: joint {i}", spec.name);
        }
        // the scripted expert's actions are in units of the same step: a goal one step away
        // on every joint is one full action
        let mut ex = Expert::for_spec(&spec);
        let mut act = vec![0.0; task.act_dim()];
        ex.act(&env.snapshot(), &mut act);
        assert!(act[..6].iter().all(|v| v.abs() <= 1.0));
    }
}

#[test]
fn the_family_joint_steps_move_the_tool_about_as_far_as_the_ur3s() {
    // One full step of the base, shoulder or elbow at each spec's home_q: the tool0 distance
    // against the UR3's, within 15 % (the layouts' scale is the reach ratio rounded down).
    let moved = |spec: &TaskSpec, joint: usize| {
        let mut q = spec.robot.home_q;
        let a = ur3_kin::fk(spec.arm(), &q);
        q[joint] += spec.joint_step();
        let b = ur3_kin::fk(spec.arm(), &q);
        (b.translation.vector - a.translation.vector).norm()
    };
    let ur3 = tile_sim::Task::TileSuction.spec();
    for file in ["tile_suction_ur5e.toml", "tile_suction_ur10e.toml"] {
        let spec = spec_file(file);
        for joint in 0..3 {
            let (d, d3) = (moved(&spec, joint), moved(&ur3, joint));
            assert!((d / d3 - 1.0).abs() < 0.15, "{file}: joint {joint} moves tool0 {d} m, the UR3's {d3} m");
        }
    }
}

/// Installs of the scripted expert over `episodes` seeds of `spec`'s paper starts.
fn expert_installs(spec: Arc<TaskSpec>, episodes: u64) -> (u64, u64) {
    let task = spec.task();
    let mut env = Env::from_spec(spec.clone(), 0);
    let mut o = vec![0.0; task.obs_dim()];
    let mut a = vec![0.0; task.act_dim()];
    let mut ex = Expert::for_spec(&spec);
    let (mut ok, mut picked) = (0, 0);
    for seed in 0..episodes {
        env.reset(Some(seed), &mut o).unwrap();
        ex.reset();
        loop {
            ex.act(&env.snapshot(), &mut a);
            let r: StepOutcome = env.step(&a, &mut o).unwrap();
            if r.terminated || r.truncated {
                ok += r.installed as u64;
                picked += r.picked as u64;
                break;
            }
        }
    }
    (ok, picked)
}

#[test]
fn expert_installs_the_tile_on_a_ur5e() {
    let (ok, picked) = expert_installs(spec_file("tile_suction_ur5e.toml"), 50);
    println!("UR5e: expert installed {ok}/50, picked {picked}/50");
    assert!(ok >= 49, "installed {ok}/50, picked {picked}/50");
}

#[test]
fn expert_installs_the_tile_on_a_ur10e() {
    let (ok, picked) = expert_installs(spec_file("tile_suction_ur10e.toml"), 50);
    println!("UR10e: expert installed {ok}/50, picked {picked}/50");
    assert!(ok >= 49, "installed {ok}/50, picked {picked}/50");
}

#[test]
fn expert_installs_the_tile_on_a_ur3e() {
    let text =
        TaskSpec::builtin_toml(tile_sim::Task::TileSuction).replace("model = \"ur3\"", "model = \"ur3e\"");
    let spec = Arc::new(TaskSpec::from_toml(&text, "tile_suction (ur3e)").unwrap());
    let (ok, picked) = expert_installs(spec, 50);
    println!("UR3e: expert installed {ok}/50, picked {picked}/50");
    assert!(ok >= 49, "installed {ok}/50, picked {picked}/50");
}
