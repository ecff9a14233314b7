//! BlockGrip: a parallel gripper picks a 4 cm wooden cube and places it on the pad. The fingers
//! close at a constant speed until they touch what lies between them, open to their limit, and
//! hold their gap otherwise. Grasp (the closing fingers stop on the block) pays +1 once; the
//! block released with its centre within [`PLACE_DIST`] of the target pays +1 and ends the
//! episode; the block leaving the table pays −0.5 and ends it. Frame (16 floats): `q[6]`, finger
//! gap (m), TCP (between the fingertips), target, block centre. The finger motion is shared with
//! [`super::screw`].

use super::suction::req;
use super::{State, TaskLogic};
use crate::CONTROL_DT;
use crate::env::StepOutcome;
use rapier3d::prelude::*;

/// BlockGrip place threshold, m (the built-in spec's `thresholds.success_dist`; the logic reads
/// the spec).
pub const PLACE_DIST: f32 = 0.02;
/// The block's centre must be this far inside the fingers' faces for them to close on it (m).
const GRASP_INSET: f32 = 0.005;

/// The BlockGrip logic.
#[derive(Debug)]
pub(crate) struct BlockGrip;

/// The fingers' part of a step: close (`cmd ≥ 0.5`) until `contact` (the gap at which the
/// fingers touch what lies between them, `None` when nothing does) is reached, then grasp: pay
/// +1 once and, when `carry`, hold the object centred between the fingers; open (`cmd ≤ −0.5`)
/// to the limit, letting go (and, when `carry`, releasing the object); otherwise hold the gap.
pub(crate) fn fingers(
    s: &mut State,
    cmd: f32,
    out: &mut StepOutcome,
    contact: impl Fn(&State) -> Option<f32>,
    carry: bool,
) {
    let (_, _, max_width, speed) = s.gripper();
    let dw = speed * CONTROL_DT;
    if cmd >= 0.5 {
        if !s.held {
            let new_w = (s.width - dw).max(0.0);
            match contact(s) {
                Some(contact_w) if new_w <= contact_w => {
                    s.width = contact_w.min(s.width);
                    if carry {
                        // The closing fingers centre the block between them.
                        let tcp = s.tcp();
                        let mut local = tcp.inverse() * s.object_pose();
                        local.translation.y = 0.0;
                        let tool_to_tcp = s.tool0.inverse() * tcp;
                        let reward = s.spec.rewards.pick;
                        s.grasp(tool_to_tcp * local, out, reward);
                    } else {
                        s.held = true;
                        let reward = s.spec.rewards.pick;
                        s.first_pick(out, reward);
                    }
                }
                _ => s.width = new_w,
            }
        }
    } else if cmd <= -0.5 {
        s.width = (s.width + dw).min(max_width);
        if s.held {
            s.held = false;
            if carry {
                s.release_object();
            }
        }
    }
    place_fingers(s, false);
}

/// Put the fingers at the current gap on tool0 (their next kinematic pose; also the current one
/// when `teleport`).
pub(crate) fn place_fingers(s: &mut State, teleport: bool) {
    if let Some(f) = s.h.fingers {
        let (finger_half, finger_z, _, _) = s.gripper();
        for (k, sign) in [(0usize, 1.0f32), (1, -1.0)] {
            let p = s.tool0
                * Pose::from_translation(Vector::new(0.0, sign * (s.width / 2.0 + finger_half[1]), finger_z));
            if let Some(b) = s.world.bodies.get_mut(f[k]) {
                if teleport {
                    b.set_position(p, true);
                }
                b.set_next_kinematic_position(p);
            }
        }
    }
}

/// The gap at which the fingers touch the block, if it lies between them: its extent across the
/// fingers, when its centre is within the fingers' faces (5 mm in from their edges) and the gap.
fn block_contact(s: &State) -> Option<f32> {
    let tcp = s.tcp();
    let obj = s.object_pose();
    let (finger_half, _, _, _) = s.gripper();
    let h = s.spec.object.half_extents.unwrap_or([0.0; 3]);
    let p = tcp.inverse_transform_point(obj.translation);
    let tool_y = tcp.rotation * Vector::Y;
    let tool_x = tcp.rotation * Vector::X;
    let tool_z = tcp.rotation * Vector::Z;
    // The block's half extent along `u`; a cube's in one product, as it always was computed.
    let ext = |u: Vector| {
        let r = obj.rotation;
        let (ax, ay, az) =
            ((r * Vector::X).dot(u).abs(), (r * Vector::Y).dot(u).abs(), (r * Vector::Z).dot(u).abs());
        if h[0] == h[1] && h[1] == h[2] { h[0] * (ax + ay + az) } else { h[0] * ax + h[1] * ay + h[2] * az }
    };
    let (ex, ey, ez) = (ext(tool_x), ext(tool_y), ext(tool_z));
    let inside = p.x.abs() < finger_half[0] + ex - GRASP_INSET
        && p.z.abs() < finger_half[2] + ez - GRASP_INSET
        && p.y.abs() < s.width / 2.0;
    inside.then_some(2.0 * ey)
}

impl TaskLogic for BlockGrip {
    fn obs_frame_dim(&self) -> usize {
        16
    }

    fn act_dim(&self) -> usize {
        7
    }

    fn reset(&self, s: &mut State) {
        let open = s.gripper().2;
        s.reset_effector(open);
    }

    fn place_attached(&self, s: &mut State, teleport: bool) {
        place_fingers(s, teleport);
    }

    fn effector(&self, s: &mut State, action: &[f32], out: &mut StepOutcome) {
        fingers(s, action[6], out, block_contact, true);
    }

    fn evaluate(&self, s: &mut State, out: &mut StepOutcome) {
        let (p, v) = s.object_state();
        let t = &s.spec.thresholds;
        if !s.held && (p.translation - s.target.translation).length() < req(t.success_dist) {
            out.reward += s.spec.rewards.success;
            out.installed = true;
            out.terminated = true;
        } else if !p.is_finite() || p.translation.z < req(t.fall_z) || (!s.held && v.z < -req(t.fall_speed)) {
            out.reward += s.spec.rewards.fail;
            out.fell = true;
            out.terminated = true;
        }
    }

    fn write_frame(&self, s: &State, f: &mut [f32]) {
        s.write_frame(&[s.width], f);
    }
}
