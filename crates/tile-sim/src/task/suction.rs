//! TileSuction (paper §5.1): a four-cup suction head picks a ceramic tile and installs it on the
//! pad. Suction on with the cup centre within [`PICK_DIST`] of the tile's grasp point (the centre
//! of its upper face) holds the tile rigidly and pays +1 once; the tile's centre within
//! [`INSTALL_DIST`] of the target pays +1 and ends the episode, held or not; a fall pays −0.5 and
//! ends it. Frame (16 floats): `q[6]`, suction (+1 on / −1 off), cup centre, target, tile centre.

use super::{State, TaskLogic};
use crate::env::StepOutcome;
use crate::spec::TaskSpec;
use rapier3d::prelude::*;

/// Pick threshold: cup centre to grasp point (paper §5.1), m (the built-in spec's
/// `thresholds.pick_dist`; the logic reads the spec).
pub const PICK_DIST: f32 = 0.04;
/// Install threshold: tile centre to target (paper §5.1), m (`thresholds.success_dist`).
pub const INSTALL_DIST: f32 = 0.03;
/// Fall rules: centre below this height (m, the table top is 0), tilt above 45°, or falling
/// faster than `FALL_SPEED` (m/s) while not held (`thresholds.fall_z`, `fall_speed`).
pub const FALL_Z: f32 = -0.02;
pub const FALL_SPEED: f32 = 1.0;

/// A threshold the spec check made sure is there.
pub(crate) fn req<T>(v: Option<T>) -> T {
    v.expect("invariant: TaskSpec::check requires the thresholds its logic reads")
}

/// The TileSuction logic.
#[derive(Debug)]
pub(crate) struct Suction;

/// The suction command `action[6]`: ≥ 0.5 turns the suction on, ≤ −0.5 off, between keeps it;
/// a held object is let go once the suction is off (TileSuction and TileRow).
pub(super) fn switch_suction(s: &mut State, action: &[f32]) {
    let cmd = action[6];
    if cmd >= 0.5 {
        s.suction_on = true;
    } else if cmd <= -0.5 {
        s.suction_on = false;
    }
    if s.held && !s.suction_on {
        s.held = false;
        s.release_object();
    }
}

/// Where the cups take a tile: the centre of its face turned up (the one the cups reach),
/// `half` (the object's half height) from its centre along its z axis.
pub(super) fn grasp_point(tile: &Pose, half: f32) -> Vector {
    let up = tile.rotation * Vector::Z;
    let sign = if up.z >= 0.0 { 1.0 } else { -1.0 };
    tile.translation + up * (sign * half)
}

/// TileSuction's fall rules for an object at `p` moving at `v` (held or not).
pub(crate) fn fell(spec: &TaskSpec, p: &Pose, v: Vector, held: bool) -> bool {
    let t = &spec.thresholds;
    if !p.is_finite() || p.translation.z < req(t.fall_z) {
        return true;
    }
    if held {
        return false;
    }
    (p.rotation * Vector::Z).z.abs() < req(t.fall_tilt_cos) || v.z < -req(t.fall_speed)
}

impl TaskLogic for Suction {
    fn obs_frame_dim(&self) -> usize {
        16
    }

    fn act_dim(&self) -> usize {
        7
    }

    fn reset(&self, s: &mut State) {
        s.reset_effector(0.0);
    }

    fn gripper_width(&self, _s: &State) -> f64 {
        0.0
    }

    fn effector(&self, s: &mut State, action: &[f32], out: &mut StepOutcome) {
        switch_suction(s, action);
        if !s.held && s.suction_on {
            let tile = s.object_pose();
            let grasp = grasp_point(&tile, s.spec.object_half_height());
            if (s.tcp().translation - grasp).length() < req(s.spec.thresholds.pick_dist) {
                let gap = super::tile_place::lip_gap(s.tcp().translation, &tile, s.spec.object_half_height());
                s.hold_gaps.push(gap);
                let offset = s.tool0.inverse() * tile;
                let reward = s.spec.rewards.pick;
                s.grasp(offset, out, reward);
            }
        }
    }

    fn evaluate(&self, s: &mut State, out: &mut StepOutcome) {
        let (p, v) = s.object_state();
        if (p.translation - s.target.translation).length() < req(s.spec.thresholds.success_dist) {
            out.reward += s.spec.rewards.success;
            out.installed = true;
            out.terminated = true;
        } else if fell(&s.spec, &p, v, s.held) {
            out.reward += s.spec.rewards.fail;
            out.fell = true;
            out.terminated = true;
        }
    }

    fn write_frame(&self, s: &State, f: &mut [f32]) {
        let suction = if s.suction_on { 1.0 } else { -1.0 };
        s.write_frame(&[suction], f);
    }
}
