//! How an action's first six numbers move the arm: the spec's `robot.action` space.
//!
//! * **joint** (the default, the paper's): `a[i]` turns joint `i` by `a[i] · joint_step` rad.
//! * **tool**: `a[0..3]` moves the TCP (the cup lips or the point between the fingertips) by
//!   `a[0..3] · tool_step` m along Base x, y, z and `a[3..6]` turns it by `a[3..6] · tool_turn`
//!   rad about Base x, y, z (a rotation vector), as a UR's `speedL` / `servoL` commands the tool.
//!   The joints take the motion the Jacobian at the TCP asks for (`dq = J⁻¹ · twist`), scaled
//!   down as a whole when a joint would turn more than `joint_step` (the arm's speed limit keeps
//!   the direction), and none at all where the Jacobian is singular.
//!
//! In both spaces the joints are clamped to `[−π, π]` (never wrapped). [`action_toward`] is the
//! inverse: the action that moves the arm from `q` towards `q_goal` in one step (as far as one
//! step may), which the scripted expert, the teleop session and demogen record.

use crate::spec::{ActionSpace, TaskSpec};
use nalgebra::{Matrix6, UnitQuaternion, Vector3, Vector6};
use std::f64::consts::PI;
use ur3_kin::{Joints, Pose};

/// TCP motion (m) per step at full action in the tool space, when the spec sets no `tool_step`
/// (0.25 m/s at the 25 Hz control rate: a UR3's TCP moves about as far at a full joint step).
pub const TOOL_STEP: f64 = 0.01;
/// TCP turn (rad) per step at full action in the tool space, when the spec sets no `tool_turn`
/// (1 rad/s, the joint space's [`MAX_JOINT_STEP`](crate::MAX_JOINT_STEP)).
pub const TOOL_TURN: f64 = 0.04;

/// The TCP's pose in Base at joint angles `q` (tool0 moved `tcp_z` along its z axis).
fn tcp(spec: &TaskSpec, q: &Joints) -> Pose {
    ur3_kin::fk(spec.arm(), q) * nalgebra::Translation3::new(0.0, 0.0, f64::from(spec.tcp_z()))
}

/// The Jacobian at the TCP (Base frame; rows: TCP linear velocity, then angular velocity).
fn tcp_jacobian(spec: &TaskSpec, q: &Joints) -> Matrix6<f64> {
    let j = ur3_kin::jacobian(spec.arm(), q);
    let r = ur3_kin::fk(spec.arm(), q).rotation * Vector3::new(0.0, 0.0, f64::from(spec.tcp_z()));
    let mut out = j;
    for c in 0..6 {
        let w = Vector3::new(j[(3, c)], j[(4, c)], j[(5, c)]);
        let v = Vector3::new(j[(0, c)], j[(1, c)], j[(2, c)]) + w.cross(&r);
        out[(0, c)] = v.x;
        out[(1, c)] = v.y;
        out[(2, c)] = v.z;
    }
    out
}

/// The joint angles one step of action `a` (its first six numbers, each clipped to `[−1, 1]`)
/// takes the arm to from `q`.
pub fn joint_motion(spec: &TaskSpec, q: &Joints, a: &[f32]) -> Joints {
    let step = spec.joint_step();
    let dq: [f64; 6] = match spec.action_space() {
        ActionSpace::Joint => std::array::from_fn(|i| f64::from(a[i].clamp(-1.0, 1.0)) * step),
        ActionSpace::Tool => {
            let (ts, tt) = (spec.tool_step(), spec.tool_turn());
            let twist =
                Vector6::from_fn(|i, _| f64::from(a[i].clamp(-1.0, 1.0)) * if i < 3 { ts } else { tt });
            match tcp_jacobian(spec, q).lu().solve(&twist) {
                Some(d) if d.iter().all(|x| x.is_finite()) => {
                    let most = d.amax();
                    let k = if most > step { step / most } else { 1.0 };
                    std::array::from_fn(|i| d[i] * k)
                }
                _ => [0.0; 6],
            }
        }
    };
    std::array::from_fn(|i| (q[i] + dq[i]).clamp(-PI, PI))
}

/// The action (six numbers in `[−1, 1]`) that moves the arm from `q` towards `q_goal` in one
/// step: joint space, each joint's difference (the short way round) over `joint_step`, each
/// clipped; tool space, the TCP's displacement over `tool_step` and its turn (a rotation vector,
/// Base) over `tool_turn`, scaled down together when one is beyond 1 (a straight line to the
/// goal).
pub fn action_toward(spec: &TaskSpec, q: &Joints, q_goal: &Joints) -> [f64; 6] {
    match spec.action_space() {
        ActionSpace::Joint => {
            let step = spec.joint_step();
            std::array::from_fn(|i| (ur3_kin::wrap_angle(q_goal[i] - q[i]) / step).clamp(-1.0, 1.0))
        }
        ActionSpace::Tool => {
            let (now, goal) = (tcp(spec, q), tcp(spec, q_goal));
            let d = goal.translation.vector - now.translation.vector;
            let turn: UnitQuaternion<f64> = goal.rotation * now.rotation.inverse();
            let w = turn.scaled_axis();
            let (ts, tt) = (spec.tool_step(), spec.tool_turn());
            let raw: [f64; 6] = std::array::from_fn(|i| if i < 3 { d[i] / ts } else { w[i - 3] / tt });
            // scaled as a whole (not clipped one by one): the TCP heads straight for the goal
            let most = raw.iter().fold(1.0f64, |m, x| m.max(x.abs()));
            raw.map(|x| x / most)
        }
    }
}
