//! Screw: the gripper grips the nut threaded on a fixed M12 bolt and spins it down
//! [`SCREW_TURNS`] turns. Gripping the nut pays +1 once; `turns ≥ SCREW_TURNS` pays +1 and ends
//! the episode; loosened more than one turn (the nut leaves the bolt) pays −0.5 and ends it. The
//! nut rides the thread (kinematic, placed from the turn count); it turns at the spin rate while
//! gripped with the flange within ~20° of vertical, and the fingers slip off when the TCP moves
//! more than 1 cm from it. Frame (18 floats): `q[6]`, finger gap (m), spin (+1 / 0 / −1), TCP,
//! target (the nut's tightened centre), nut centre, turns.

use super::gripper::{fingers, place_fingers};
use super::{State, TaskLogic};
use crate::env::StepOutcome;
use crate::{CONTROL_DT, SCREW_TURNS, world};
use rapier3d::prelude::*;
use std::f64::consts::PI;

/// The screwing TCP must point down within ~20° of the bolt axis.
const ALIGN_COS: f32 = 0.94;

/// The Screw logic.
#[derive(Debug)]
pub(crate) struct Screw;

/// Place the nut on the thread from the turn count (next kinematic pose; also the current one
/// when `teleport`).
pub(crate) fn place_nut(s: &mut State, teleport: bool) {
    let z = world::NUT_START_Z - (s.turns as f32) * world::THREAD_PITCH;
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
    let tcp = s.tcp_at(world::GRIP_TCP_Z);
    let p = tcp.inverse_transform_point(s.object_pose().translation);
    let tool_z = tcp.rotation * Vector::Z;
    let aligned = tool_z.dot(-Vector::Z) > ALIGN_COS;
    let inside = aligned
        && p.x.abs() < 0.006
        && p.y.abs() < 0.006
        && p.z.abs() < world::FINGER_HALF[2] - world::NUT_HALF_HEIGHT
        && world::NUT_RADIUS <= s.width / 2.0 + 1e-4;
    inside.then_some(2.0 * world::NUT_RADIUS)
}

impl TaskLogic for Screw {
    fn obs_frame_dim(&self) -> usize {
        18
    }

    fn act_dim(&self) -> usize {
        8
    }

    fn tcp_z(&self) -> f32 {
        world::GRIP_TCP_Z
    }

    fn reset(&self, s: &mut State) {
        s.suction_on = false;
        s.width = world::GRIP_MAX_WIDTH;
        s.spin = 0;
        s.turns = 0.0;
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
            let tcp = s.tcp_at(world::GRIP_TCP_Z);
            let d = tcp.translation - s.object_pose().translation;
            let aligned = (tcp.rotation * Vector::Z).dot(-Vector::Z) > ALIGN_COS;
            if !aligned || d.length() > 0.01 {
                // The arm pulled away: the fingers slip off the nut.
                s.held = false;
            } else if s.spin != 0 {
                s.turns += s.spin as f64 * (world::SPIN_RATE * CONTROL_DT) as f64;
            }
        }
        place_nut(s, false);
    }

    fn evaluate(&self, s: &State, out: &mut StepOutcome) {
        if s.turns >= SCREW_TURNS - 1e-9 {
            out.reward += 1.0;
            out.installed = true;
            out.terminated = true;
        } else if s.turns < -1.0 {
            out.reward -= 0.5;
            out.fell = true;
            out.terminated = true;
        }
    }

    fn write_frame(&self, s: &State, f: &mut [f32]) {
        let k = s.write_frame(self.tcp_z(), &[s.width, s.spin as f32], f);
        f[k] = s.turns as f32;
    }
}
