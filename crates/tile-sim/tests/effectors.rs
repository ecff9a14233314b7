//! Gripper and screwing end effectors, and the scripted experts' success rates.

use nalgebra::Vector3;
use tile_sim::expert::{Expert, ik_dls, tool0_for_tcp};
use tile_sim::world::{
    BLOCK_HALF, GRIP_MAX_WIDTH, GRIP_SPEED, GRIP_TCP_Z, NUT_RADIUS, SPIN_RATE, THREAD_PITCH,
};
use tile_sim::{CONTROL_DT, Env, SCREW_TURNS, Task};

fn place_tcp(env: &mut Env, tcp: [f64; 3]) {
    let s = env.snapshot();
    let goal = tool0_for_tcp(Vector3::new(tcp[0], tcp[1], tcp[2]), GRIP_TCP_Z as f64);
    env.set_joints(ik_dls(&goal, &s.q).expect("reachable")).unwrap();
}

fn a8(cmd: f32, spin: f32) -> [f32; 8] {
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, cmd, spin]
}

const DW: f64 = (GRIP_SPEED * CONTROL_DT) as f64;

#[test]
fn gripper_closes_at_constant_speed_until_contact_opens_to_limit_fixed_holds() {
    let t = Task::BlockGrip;
    let mut env = Env::new(t, 0);
    let mut o = vec![0.0; t.obs_dim()];
    env.reset(Some(2), &mut o).unwrap();
    assert!((env.snapshot().gripper_width - GRIP_MAX_WIDTH as f64).abs() < 1e-7);
    let a = |c: f32| [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, c];
    // Closing on nothing (arm at home, far above): constant speed to zero.
    let mut w = GRIP_MAX_WIDTH as f64;
    for _ in 0..30 {
        let r = env.step(&a(1.0), &mut o).unwrap();
        w = (w - DW).max(0.0);
        assert!((env.snapshot().gripper_width - w).abs() < 1e-6);
        assert_eq!(o[4 * 16 + 6] as f64, env.snapshot().gripper_width as f32 as f64);
        assert!(!r.held);
    }
    assert_eq!(env.snapshot().gripper_width, 0.0);
    // Opening: constant speed up to the limit.
    for _ in 0..30 {
        env.step(&a(-1.0), &mut o).unwrap();
        w = (w + DW).min(GRIP_MAX_WIDTH as f64);
        assert!((env.snapshot().gripper_width - w).abs() < 1e-6);
    }
    assert!((env.snapshot().gripper_width - GRIP_MAX_WIDTH as f64).abs() < 1e-7);
    // Half close, then fixed holds the width.
    for _ in 0..5 {
        env.step(&a(1.0), &mut o).unwrap();
    }
    let held_w = env.snapshot().gripper_width;
    for _ in 0..5 {
        env.step(&a(0.0), &mut o).unwrap();
        env.step(&a(0.3), &mut o).unwrap();
        assert_eq!(env.snapshot().gripper_width, held_w);
    }
    // Open again, put the fingers around the block, close: stops at the block's width.
    for _ in 0..10 {
        env.step(&a(-1.0), &mut o).unwrap();
    }
    let b = env.snapshot().object.t;
    place_tcp(&mut env, b);
    let mut reward = 0.0;
    let mut closed = 0;
    for _ in 0..30 {
        let r = env.step(&a(1.0), &mut o).unwrap();
        reward += r.reward;
        if r.held {
            closed += 1;
        }
    }
    let s = env.snapshot();
    assert!(closed > 10, "closed {closed} obj {:?} tcp {:?} w {}", s.object.t, s.tcp.t, s.gripper_width);
    assert_eq!(reward, 1.0, "grasp pays once");
    let w = env.snapshot().gripper_width;
    // The block settles with a tiny yaw: its extent across the fingers is 0.04 m within 0.2 mm.
    assert!((w - 2.0 * BLOCK_HALF as f64).abs() < 2e-4, "stopped at contact: {w}");
    // Lift: the block comes along.
    let z0 = env.snapshot().object.t[2];
    let mut up = a(0.0);
    up[1] = -1.0;
    for _ in 0..10 {
        assert!(env.step(&up, &mut o).unwrap().held);
    }
    assert!(env.snapshot().object.t[2] > z0 + 0.05);
    // Open: released.
    let r = env.step(&a(-1.0), &mut o).unwrap();
    assert!(!r.held && r.picked);
}

#[test]
fn block_place_on_pad_and_fall() {
    let t = Task::BlockGrip;
    let mut env = Env::new(t, 0);
    let mut o = vec![0.0; t.obs_dim()];
    env.reset(Some(2), &mut o).unwrap();
    let tgt = env.snapshot().target.t;
    env.set_object_pose([tgt[0] + 0.015, tgt[1], tgt[2]], [0.0, 0.0, 0.0, 1.0]).unwrap();
    let r = env.step(&[0.0; 7], &mut o).unwrap();
    assert!(r.installed && r.terminated && r.reward == 1.0);
    env.reset(Some(2), &mut o).unwrap();
    env.set_object_pose([tgt[0] + 0.025, tgt[1], tgt[2]], [0.0, 0.0, 0.0, 1.0]).unwrap();
    let r = env.step(&[0.0; 7], &mut o).unwrap();
    assert!(!r.installed && !r.terminated && r.reward == 0.0);
    env.set_object_pose([0.9, 0.0, 0.1], [0.0, 0.0, 0.0, 1.0]).unwrap();
    let mut fell = false;
    for _ in 0..30 {
        let r = env.step(&[0.0; 7], &mut o).unwrap();
        if r.terminated {
            fell = r.fell && r.reward == -0.5;
            break;
        }
    }
    assert!(fell);
}

#[test]
fn screwing_spins_only_gripped_nut_tighten_loosen_stop() {
    let t = Task::Screw;
    let mut env = Env::new(t, 0);
    let mut o = vec![0.0; t.obs_dim()];
    env.reset(Some(6), &mut o).unwrap();
    // Spinning without a grip does nothing.
    for _ in 0..5 {
        env.step(&a8(0.0, 1.0), &mut o).unwrap();
    }
    assert_eq!(env.snapshot().spin_angle, 0.0);
    assert_eq!(o[4 * 18 + 7], 1.0, "spin state in the observation");
    let nut = env.snapshot().object.t;
    place_tcp(&mut env, nut);
    let mut grip_reward = 0.0;
    for _ in 0..20 {
        grip_reward += env.step(&a8(1.0, 0.0), &mut o).unwrap().reward;
    }
    assert_eq!(grip_reward, 1.0);
    assert!(env.snapshot().held);
    assert!((env.snapshot().gripper_width - 2.0 * NUT_RADIUS as f64).abs() < 1e-5);
    let per = (SPIN_RATE * CONTROL_DT) as f64;
    for k in 1..=10 {
        env.step(&a8(0.0, 1.0), &mut o).unwrap();
        let s = env.snapshot();
        assert!((s.spin_angle - k as f64 * per * 2.0 * std::f64::consts::PI).abs() < 1e-9);
    }
    let z10 = env.snapshot().object.t[2];
    assert!(
        (nut[2] - z10 - 10.0 * per * THREAD_PITCH as f64).abs() < 1e-6,
        "nut advances one pitch per turn"
    );
    // Stopped (and fixed) holds.
    for _ in 0..5 {
        env.step(&a8(0.0, 0.2), &mut o).unwrap();
    }
    assert!((env.snapshot().spin_angle - 10.0 * per * 2.0 * std::f64::consts::PI).abs() < 1e-9);
    // Loosen.
    for _ in 0..4 {
        env.step(&a8(0.0, -1.0), &mut o).unwrap();
    }
    assert!((env.snapshot().spin_angle - 6.0 * per * 2.0 * std::f64::consts::PI).abs() < 1e-9);
    assert!((o[4 * 18 + 17] as f64 - 6.0 * per).abs() < 1e-6, "turns in the observation");
    // Tighten to SCREW_TURNS: +1 and terminated.
    let mut total = 0.0;
    let mut done = false;
    for _ in 0..200 {
        let r = env.step(&a8(0.0, 1.0), &mut o).unwrap();
        total += r.reward;
        if r.terminated {
            assert!(r.installed);
            done = true;
            break;
        }
    }
    assert!(done && total == 1.0);
    assert!(env.snapshot().spin_angle >= SCREW_TURNS * 2.0 * std::f64::consts::PI - 1e-9);
}

#[test]
fn screw_loosened_off_the_bolt_fails() {
    let t = Task::Screw;
    let mut env = Env::new(t, 0);
    let mut o = vec![0.0; t.obs_dim()];
    env.reset(Some(1), &mut o).unwrap();
    env.set_turns(-0.98).unwrap();
    let nut = env.snapshot().object.t;
    place_tcp(&mut env, nut);
    for _ in 0..20 {
        env.step(&a8(1.0, 0.0), &mut o).unwrap();
    }
    let r = env.step(&a8(0.0, -1.0), &mut o).unwrap();
    assert!(r.fell && r.terminated && r.reward == -0.5);
}

fn success_rate(task: Task, episodes: u64) -> (u64, u64) {
    let mut env = Env::new(task, 0);
    let mut o = vec![0.0; task.obs_dim()];
    let mut a = vec![0.0; task.act_dim()];
    let mut ex = Expert::new(task);
    let (mut ok, mut picked) = (0, 0);
    for seed in 0..episodes {
        env.reset(Some(seed), &mut o).unwrap();
        ex.reset();
        loop {
            ex.act(&env.snapshot(), &mut a);
            // The expert's action is a valid demonstration action.
            assert!(a[..6].iter().all(|v| v.abs() <= 1.0));
            assert!([-1.0, 0.0, 1.0].contains(&a[6]));
            let r = env.step(&a, &mut o).unwrap();
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
fn expert_completes_tile_suction_in_99_percent_of_1000_seeds() {
    let (ok, picked) = success_rate(Task::TileSuction, 1000);
    eprintln!("TileSuction expert: installed {ok}/1000, picked {picked}/1000");
    assert!(ok >= 990, "installed {ok}/1000");
}

#[test]
fn experts_complete_grip_and_screw() {
    for task in [Task::BlockGrip, Task::Screw] {
        let (ok, _) = success_rate(task, 200);
        eprintln!("{task:?} expert: {ok}/200");
        assert!(ok >= 190, "{task:?}: {ok}/200");
    }
}

/// Skipping the solver while nothing dynamic can move changes no outcome: expert
/// episodes with and without the skip end the same way at the same step with the object in the
/// same place, and random-action episodes give the same rewards.
#[test]
fn idle_physics_skip_is_exact() {
    for task in Task::ALL {
        let mut skipped = 0;
        for seed in 0..20u64 {
            let mut runs = Vec::new();
            for skip in [true, false] {
                let mut env = Env::new(task, 0);
                env.set_skip_idle_physics(skip);
                let mut o = vec![0.0; task.obs_dim()];
                let mut a = vec![0.0; task.act_dim()];
                let mut ex = Expert::new(task);
                env.reset(Some(seed), &mut o).unwrap();
                let mut rewards = Vec::new();
                loop {
                    ex.act(&env.snapshot(), &mut a);
                    let r = env.step(&a, &mut o).unwrap();
                    rewards.push(r.reward);
                    if r.terminated || r.truncated {
                        break;
                    }
                }
                if skip {
                    skipped += env.skipped_steps();
                }
                runs.push((rewards, env.snapshot()));
            }
            let (r0, s0) = &runs[0];
            let (r1, s1) = &runs[1];
            assert_eq!(r0, r1, "{task:?} seed {seed}");
            for i in 0..3 {
                // Same outcome; poses agree to f32 solver noise (the released body starts from a
                // freshly woken state either way).
                assert!((s0.object.t[i] - s1.object.t[i]).abs() < 1e-4, "{task:?} seed {seed}");
            }
        }
        assert!(skipped > 100, "{task:?}: the skip is exercised ({skipped})");
    }
}
