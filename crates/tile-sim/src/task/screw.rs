//! Screw: the gripper grips the nut threaded on a fixed M12 bolt and spins it down
//! [`SCREW_TURNS`] turns. Gripping the nut pays +1 once; `turns ≥ SCREW_TURNS` pays +1 and ends
//! the episode; loosened more than one turn (the nut leaves the bolt) pays −0.5 and ends it. The
//! nut rides the thread (kinematic, placed from the turn count); it turns at the spin rate while
//! gripped with the flange within ~20° of vertical, and the fingers slip off when the TCP moves
//! more than 1 cm from it. Frame (18 floats): `q[6]`, finger gap (m), spin (+1 / 0 / −1), TCP,
//! target (the nut's tightened centre), nut centre, turns.

use super::gripper::{fingers, place_fingers};
use super::suction::req;
use super::{State, TaskLogic};
use crate::env::StepOutcome;
use crate::spec::{EffectorSpec, TargetSpec};
use crate::starts::nut_start_z;
use crate::{CONTROL_DT, SCREW_TURNS};
use rapier3d::prelude::*;
use std::f64::consts::PI;

/// The nut's centre must be within this distance of the TCP across the fingers to be gripped (m).
const CENTRE_TOL: f32 = 0.006;
/// Slack (m) of the finger gap over the nut's width for the fingers to go around it.
const GAP_SLACK: f32 = 1e-4;

/// (thread pitch m/turn, turns for success) of the spec's bolt.
fn bolt(s: &State) -> (f32, f64) {
    match &s.spec.target {
        TargetSpec::Bolt { pitch, turns, .. } => (*pitch, *turns),
        TargetSpec::Pad { .. } => (0.0, SCREW_TURNS),
    }
}

/// The Screw logic.
#[derive(Debug)]
pub(crate) struct Screw;

/// Place the nut on the thread from the turn count (next kinematic pose; also the current one
/// when `teleport`).
pub(crate) fn place_nut(s: &mut State, teleport: bool) {
    let z = nut_start_z(&s.spec) - (s.turns as f32) * bolt(s).0;
    let ang = (s.turns * 2.0 * PI) as f32;
    // Tightening a right-hand thread turns the nut clockwise seen from above (−Z rotation).
    let p = Pose::from_parts(
        Vector::new(s.start.object_xy[0], s.start.object_xy[1], z),
        Rotation::from_rotation_z(-ang),
    );
    if let Some(b) = s.world.bodies.get_mut(s.h.object) {
        if teleport {
            b.set_position(p, true);
        }
        b.set_next_kinematic_position(p);
    }
}

/// The gap at which the fingers touch the nut: when the flange points down and the nut's centre
/// is between the fingertips (within 6 mm of the TCP across, inside the fingers' length) and the
/// gap is open wide enough.
fn nut_contact(s: &State) -> Option<f32> {
    let tcp = s.tcp();
    let p = tcp.inverse_transform_point(s.object_pose().translation);
    let tool_z = tcp.rotation * Vector::Z;
    let aligned = tool_z.dot(-Vector::Z) > req(s.spec.thresholds.align_cos);
    let (finger_half, _, _, _) = s.gripper();
    let nut_radius = s.spec.object.radius.unwrap_or(0.0);
    let inside = aligned
        && p.x.abs() < CENTRE_TOL
        && p.y.abs() < CENTRE_TOL
        && p.z.abs() < finger_half[2] - s.spec.object_half_height()
        && nut_radius <= s.width / 2.0 + GAP_SLACK;
    inside.then_some(2.0 * nut_radius)
}

impl TaskLogic for Screw {
    fn obs_frame_dim(&self) -> usize {
        18
    }

    fn act_dim(&self) -> usize {
        8
    }

    fn reset(&self, s: &mut State) {
        let open = s.gripper().2;
        s.reset_effector(open);
    }

    fn carries_object(&self) -> bool {
        false
    }

    fn place_attached(&self, s: &mut State, teleport: bool) {
        place_fingers(s, teleport);
        place_nut(s, teleport);
    }

    fn effector(&self, s: &mut State, action: &[f32], out: &mut StepOutcome) {
        fingers(s, action[6], out, nut_contact, false);
        let spin = action[7];
        s.spin = if spin >= 0.5 {
            1
        } else if spin <= -0.5 {
            -1
        } else {
            0
        };
        if s.held {
            let tcp = s.tcp();
            let d = tcp.translation - s.object_pose().translation;
            let t = &s.spec.thresholds;
            let aligned = (tcp.rotation * Vector::Z).dot(-Vector::Z) > req(t.align_cos);
            if !aligned || d.length() > req(t.slip_dist) {
                // The arm pulled away: the fingers slip off the nut.
                s.held = false;
            } else if s.spin != 0 {
                let rate = match s.spec.effector {
                    EffectorSpec::Gripper { spin_rate: Some(r), .. } => r,
                    _ => 0.0,
                };
                s.turns += s.spin as f64 * (rate * CONTROL_DT) as f64;
            }
        }
        place_nut(s, false);
    }

    fn evaluate(&self, s: &mut State, out: &mut StepOutcome) {
        if s.turns >= bolt(s).1 - 1e-9 {
            out.reward += s.spec.rewards.success;
            out.installed = true;
            out.terminated = true;
        } else if s.turns < -req(s.spec.thresholds.fail_turns) {
            out.reward += s.spec.rewards.fail;
            out.fell = true;
            out.terminated = true;
        }
    }

    fn write_frame(&self, s: &State, f: &mut [f32]) {
        let k = s.write_frame(&[s.width, s.spin as f32], f);
        f[k] = s.turns as f32;
    }
}
