//! The action spaces (`robot.action`): joint motions (the paper's) and the TCP's motion and turn
//! (TilePlace), and `action_toward`, the action the expert, the teleop session and demogen record.

use proptest::prelude::*;
use std::f64::consts::PI;
use tile_sim::action::{TOOL_STEP, TOOL_TURN, action_toward, joint_motion};
use tile_sim::spec::ActionSpace;
use tile_sim::{SpecError, Task, TaskSpec};
use ur3_kin::{Joints, Pose};

fn place() -> std::sync::Arc<TaskSpec> {
    TaskSpec::builtin(Task::TilePlace)
}

fn tcp(spec: &TaskSpec, q: &Joints) -> Pose {
    ur3_kin::fk(spec.arm(), q) * nalgebra::Translation3::new(0.0, 0.0, f64::from(spec.tcp_z()))
}

/// Joint angles around the spec's home pose (the arm's working region).
fn near_home() -> impl Strategy<Value = Joints> {
    prop::array::uniform6(-0.4f64..0.4).prop_map(|d| {
        let h = place().robot.home_q;
        std::array::from_fn(|i| h[i] + d[i])
    })
}

#[test]
fn tileplace_commands_the_tool_and_the_paper_task_the_joints() {
    assert_eq!(place().action_space(), ActionSpace::Tool);
    assert_eq!((place().tool_step(), place().tool_turn()), (TOOL_STEP, TOOL_TURN));
    assert_eq!(TaskSpec::builtin(Task::TileSuction).action_space(), ActionSpace::Joint);
}

#[test]
fn a_tool_action_moves_the_tcp_along_base_axes_by_its_share_of_the_tool_step() {
    // Half actions: a full one along y at home would turn a wrist joint more than its step, and
    // the speed cap would shorten the move (tested below).
    let spec = place();
    let q = spec.robot.home_q;
    let t0 = tcp(&spec, &q);
    for axis in 0..3 {
        for sign in [-0.5f32, 0.5] {
            let mut a = [0.0f32; 7];
            a[axis] = sign;
            let t1 = tcp(&spec, &joint_motion(&spec, &q, &a));
            let d = t1.translation.vector - t0.translation.vector;
            let mut want = nalgebra::Vector3::zeros();
            want[axis] = f64::from(sign) * TOOL_STEP;
            // first order in one step of 5 mm: the error is the Jacobian's change over it
            assert!((d - want).norm() < 1e-4, "axis {axis} {sign}: moved {d:?}");
            assert!(t1.rotation.angle_to(&t0.rotation) < 2e-3, "axis {axis}: the tool turned");
        }
    }
    // a full action along y: the wrist would turn more than its step, so the arm moves less
    // than a tool step, along y still (the cap scales the joints' motion as a whole)
    let mut a = [0.0f32; 7];
    a[1] = 1.0;
    let d = tcp(&spec, &joint_motion(&spec, &q, &a)).translation.vector - t0.translation.vector;
    assert!(d.y > 0.5 * TOOL_STEP && d.y < 0.95 * TOOL_STEP, "{d:?}");
    assert!(d.x.abs().max(d.z.abs()) < 0.03 * d.y, "{d:?}");
    // a half turn action about Base z turns the TCP by half a tool_turn about its own point
    let mut a = [0.0f32; 7];
    a[5] = 0.5;
    let t1 = tcp(&spec, &joint_motion(&spec, &q, &a));
    let turn = t1.rotation * t0.rotation.inverse();
    let w = turn.scaled_axis();
    assert!((w.z - 0.5 * TOOL_TURN).abs() < 1e-4 && w.x.abs() < 1e-3 && w.y.abs() < 1e-3, "{w:?}");
    assert!((t1.translation.vector - t0.translation.vector).norm() < 2e-4);
}

#[test]
fn the_spec_sets_the_tool_step_and_checks_it() {
    let base = TaskSpec::builtin_toml(Task::TilePlace);
    let at = "action = \"tool\"\n";
    assert_eq!(base.matches(at).count(), 1);
    let slow = base.replacen(at, "action = \"tool\"\ntool_step = 0.005\ntool_turn = 0.02\n", 1);
    let spec = TaskSpec::from_toml(&slow, "slow.toml").unwrap();
    let q = spec.robot.home_q;
    let mut a = [0.0f32; 7];
    a[2] = 1.0;
    let dz = tcp(&spec, &joint_motion(&spec, &q, &a)).translation.z - tcp(&spec, &q).translation.z;
    assert!((dz - 0.005).abs() < 1e-4, "{dz}");
    for (edit, field, why) in [
        ("action = \"tool\"\ntool_step = 0.08\n", "robot.tool_step", "at most 0.05"),
        ("action = \"tool\"\ntool_turn = -0.01\n", "robot.tool_turn", "> 0"),
        ("action = \"tool\"\ntool_step = nan\n", "robot.tool_step", "finite"),
        ("action = \"joint\"\ntool_step = 0.01\n", "robot.tool_step", "only with robot.action = \"tool\""),
    ] {
        match TaskSpec::from_toml(&base.replacen(at, edit, 1), "bad.toml") {
            Err(SpecError::Invalid { field: f, reason, .. }) => {
                assert_eq!(f, field, "{edit}");
                assert!(reason.contains(why), "{edit}: {reason}");
            }
            other => panic!("{edit}: expected {field} refused, got {other:?}"),
        }
    }
    let e = TaskSpec::from_toml(&base.replacen(at, "action = \"cartesian\"\n", 1), "bad.toml").unwrap_err();
    assert!(e.to_string().contains("cartesian"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn the_joint_action_takes_the_short_way_and_is_bounded(
        q in prop::array::uniform6(-PI..PI),
        dq in prop::array::uniform6(-10.0f64..10.0),
    ) {
        let spec = TaskSpec::builtin(Task::TileSuction);
        let step = spec.joint_step();
        let goal: Joints = std::array::from_fn(|i| q[i] + dq[i]);
        let a = action_toward(&spec, &q, &goal);
        for i in 0..6 {
            prop_assert!(a[i].abs() <= 1.0);
            let short = ur3_kin::wrap_angle(dq[i]);
            if short.abs() < step {
                prop_assert!((a[i] - short / step).abs() < 1e-6, "{} vs {}", a[i], short / step);
            } else if (short.abs() - PI).abs() > 1e-9 {
                // half a turn either way is equally short: only then may the sign differ
                prop_assert_eq!(a[i].signum(), short.signum());
            }
        }
    }

    #[test]
    fn no_tool_action_turns_a_joint_more_than_its_step(
        q in near_home(),
        a in prop::array::uniform7(-3.0f32..3.0),
    ) {
        let spec = place();
        let qn = joint_motion(&spec, &q, &a);
        for i in 0..6 {
            prop_assert!((qn[i] - q[i]).abs() <= spec.joint_step() + 1e-12, "joint {i}: {}", qn[i] - q[i]);
        }
    }

    #[test]
    fn stepping_the_action_toward_a_goal_reaches_it(
        q in near_home(),
        d in prop::array::uniform6(-0.3f64..0.3),
    ) {
        // A goal within the arm's region: the tool-space actions towards it, step after step,
        // bring the TCP onto the goal's pose (straight in Base, the joints on the same branch).
        let spec = place();
        let goal: Joints = std::array::from_fn(|i| q[i] + d[i]);
        let want = tcp(&spec, &goal);
        let mut x = q;
        for _ in 0..200 {
            let a = action_toward(&spec, &x, &goal);
            prop_assert!(a.iter().all(|v| v.abs() <= 1.0));
            let af: Vec<f32> = a.iter().map(|&v| v as f32).collect();
            x = joint_motion(&spec, &x, &af);
        }
        let got = tcp(&spec, &x);
        prop_assert!((got.translation.vector - want.translation.vector).norm() < 1e-4,
            "{:?} vs {:?}", got.translation, want.translation);
        prop_assert!(got.rotation.angle_to(&want.rotation) < 1e-3);
    }
}
