//! TileRow (issue 26 §2): TileSuction's suction head installs a row of tiles, one after another,
//! in one episode. The spec's `[row]` ([`RowSpec`](crate::spec::RowSpec)) lays out `count` tiles
//! and `count` pads; tile `i` belongs on pad `i`. Frame (43 floats): TileSuction's 16 (`q[6]`,
//! suction +1 on / −1 off, cup centre, then the current tile's target and centre: see [The
//! current tile](#the-current-tile)), the current tile's centre minus the cup centre and its
//! target minus its centre (6), then per tile `i` of [`MAX_ROW`]: target `i`, tile `i`'s
//! centre, installed flag (1 / 0); a row shorter than [`MAX_ROW`] leaves the last slots zero.
//! Base frame, metres. The current tile's six floats repeat one tile's slot: they say which tile
//! the row is at, so a policy reads "the tile to handle now" where TileSuction's reads its tile,
//! and the same carry serves each tile of the row (with only the per-tile slots, a learner has
//! to find the first tile not installed from the flags, and a skill learnt on the last tile does
//! not carry over to the middle one). The two differences say the same in the terms a reach and
//! a carry are judged in (ManiSkill's pick tasks observe `tcp_to_obj_pos` and `obj_to_goal_pos`
//! beside the poses): with the absolute positions only, the row learner installed the first two
//! tiles but no longer the third on one seed in three (docs/tasks.md, "Learning a row").
//!
//! # Rules (what and why)
//! * **Pick**: the suction on with the cup centre within `thresholds.pick_dist` of a tile's
//!   grasp point (the centre of its upper face, as TileSuction) holds that tile (the nearest one
//!   if two qualify). Each tile's first pick pays `rewards.pick` (+1), so a success picks up
//!   three rewards for picks, and re-picking a tile (to correct it) pays nothing.
//! * **Install** of tile `i`: released (not held), resting (linear speed below [`REST_SPEED`])
//!   and its centre within `thresholds.success_dist` of target `i` (the centre of a tile lying
//!   on pad `i`'s centre). TileSuction counts an install while the tile is still held (the
//!   paper's rule for a one-tile episode, which ends there); a row goes on after an install, so
//!   a tile counts only once it has been let go and stays on its pad. It is latched: paid
//!   (`rewards.success`, +1) once, and the tile stays installed if it is later knocked off its
//!   pad (that is judged by the fall rules, which end the episode), so the reward sum of an
//!   episode is at most `count · (pick + success)`.
//! * **In order** (`row.in_order`, on in the built-in row): tile `i` may be picked only once
//!   tiles `0..i` are installed; the suction switched on within `pick_dist` of a tile whose turn
//!   has not come pays `rewards.fail` and ends the episode (`StepOutcome::fell`, the failure
//!   flag), and the tile is not gripped. Off, the tiles may be picked in any order. Why on: the
//!   row learner's seed 1 picked the middle tile first (from the home pose it is the nearest,
//!   and its pick and install pay as much as tile 0's), a row no demo continues from.
//! * **Tile `i` on pad `i`**, not any free pad: each tile's target is then fixed for the whole
//!   episode, so the observation's target `i` beside tile `i` is the goal a policy reads (with
//!   any free pad, the goal of a tile would depend on which pads the others took, which the frame
//!   would have to spell out); and the order of the row is the demonstration's, which a human
//!   shows the same way every time.
//! * **Fall**: any tile falling by TileSuction's rules (centre below `fall_z`; not held and
//!   tilted beyond `fall_tilt_cos` or falling faster than `fall_speed`) pays `rewards.fail`
//!   (−0.5) and ends the episode. Installs are judged first, so the step that completes the
//!   row is a success.
//! * **Success**: every tile installed ends the episode (terminated) with
//!   `StepOutcome::installed`; that flag marks the row complete (the task's success, as the
//!   other tasks' success flag), not each tile's install.
//!
//! # The current tile
//! The one [`State::h`]`.object` names, what the [`Env`](crate::Env)'s carrying, a snapshot's
//! `object` / `target` and [`Env::set_object_pose`](crate::Env::set_object_pose) act on: the held
//! tile while one is held, otherwise the first tile (in row order) not installed yet (the last
//! one once all are).

use super::suction::{fell, grasp_point, req, switch_suction};
use super::{State, TaskLogic};
use crate::env::{PoseRec, StepOutcome};
use crate::spec::MAX_ROW;
use rapier3d::prelude::*;

/// A released tile is resting when its centre moves slower than this (m/s): a tile let go a few
/// millimetres above its pad lands within a step or two and is then far slower; a tile sliding
/// or bouncing across the target is not installed on the way.
pub const REST_SPEED: f32 = 0.05;

/// Where the current tile's two differences begin: after TileSuction's 16 floats (the current
/// tile's target and centre at 10..16).
const REL: usize = 16;
/// Where the per-tile slots of a frame begin: after the differences (tile − cup at 16..19, target
/// − tile at 19..22).
const ROW_SLOTS: usize = REL + 6;

/// The TileRow logic.
#[derive(Debug)]
pub(crate) struct TileRow;

/// TileRow's per-tile episode state: which tiles have been picked and installed, and where each
/// belongs (the Base-frame centre of tile `i` lying on pad `i`, with the start's offsets).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RowState {
    pub(crate) picked: [bool; MAX_ROW],
    pub(crate) installed: [bool; MAX_ROW],
    pub(crate) targets: [Vector; MAX_ROW],
}

impl Default for RowState {
    fn default() -> RowState {
        RowState { picked: [false; MAX_ROW], installed: [false; MAX_ROW], targets: [Vector::ZERO; MAX_ROW] }
    }
}

/// One tile of a row in a [`Snapshot`](crate::Snapshot): its centre pose, its target (pad `i`'s),
/// and whether it has been picked and installed this episode.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RowTile {
    pub object: PoseRec,
    pub target: PoseRec,
    pub picked: bool,
    pub installed: bool,
}

fn body_state(s: &State, h: RigidBodyHandle) -> (Pose, Vector) {
    s.world.bodies.get(h).map(|b| (*b.position(), b.linvel())).unwrap_or((Pose::IDENTITY, Vector::ZERO))
}

/// The tile `i` is the one held right now.
fn held(s: &State, i: usize) -> bool {
    s.held && s.h.object == s.h.row[i]
}

/// Picking tile `i` now breaks a row laid in order (`row.in_order`): a tile before it is not
/// installed yet.
fn out_of_turn(s: &State, i: usize) -> bool {
    s.spec.row.is_some_and(|r| r.in_order) && s.row.installed[..i].iter().any(|&b| !b)
}

/// Make tile `i` the current one (its body and its target).
fn make_current(s: &mut State, i: usize) {
    s.h.object = s.h.row[i];
    s.target = Pose::from_translation(s.row.targets[i]);
}

/// The row's tiles as a snapshot lists them (empty for the other tasks).
pub(crate) fn snapshot_row(s: &State) -> Vec<RowTile> {
    (0..s.h.row.len())
        .map(|i| RowTile {
            object: PoseRec::from_pose(&body_state(s, s.h.row[i]).0),
            target: PoseRec::from_pose(&Pose::from_translation(s.row.targets[i])),
            picked: s.row.picked[i],
            installed: s.row.installed[i],
        })
        .collect()
}

impl TaskLogic for TileRow {
    fn obs_frame_dim(&self) -> usize {
        ROW_SLOTS + 7 * MAX_ROW
    }

    fn act_dim(&self) -> usize {
        7
    }

    fn reset(&self, s: &mut State) {
        s.reset_effector(0.0);
        s.row = RowState::default();
        for i in 0..s.h.row.len() {
            s.row.targets[i] = s.start.row_target(&s.spec, i);
        }
        make_current(s, 0);
    }

    fn gripper_width(&self, _s: &State) -> f64 {
        0.0
    }

    fn effector(&self, s: &mut State, action: &[f32], out: &mut StepOutcome) {
        switch_suction(s, action);
        if !s.held && s.suction_on {
            let tcp = s.tcp().translation;
            let pick_dist = req(s.spec.thresholds.pick_dist);
            let half = s.spec.object_half_height();
            let mut best: Option<(usize, f32)> = None;
            for i in 0..s.h.row.len() {
                let d = (tcp - grasp_point(&body_state(s, s.h.row[i]).0, half)).length();
                if d < pick_dist && best.is_none_or(|(_, bd)| d < bd) {
                    best = Some((i, d));
                }
            }
            if let Some((i, _)) = best {
                if out_of_turn(s, i) {
                    out.reward += s.spec.rewards.fail;
                    out.fell = true;
                    out.terminated = true;
                    return;
                }
                make_current(s, i);
                let tile = body_state(s, s.h.row[i]).0;
                s.hold_gaps.push(super::tile_place::lip_gap(tcp, &tile, half));
                let offset = s.tool0.inverse() * tile;
                s.grasp(offset, out, 0.0);
                if !s.row.picked[i] {
                    s.row.picked[i] = true;
                    out.reward += s.spec.rewards.pick;
                }
            }
        }
    }

    fn evaluate(&self, s: &mut State, out: &mut StepOutcome) {
        if out.terminated {
            return; // a pick out of turn ended the episode in `effector`
        }
        let n = s.h.row.len();
        let success_dist = req(s.spec.thresholds.success_dist);
        for i in 0..n {
            let (p, v) = body_state(s, s.h.row[i]);
            let near = (p.translation - s.row.targets[i]).length() < success_dist;
            if !s.row.installed[i] && !held(s, i) && near && v.length() < REST_SPEED {
                s.row.installed[i] = true;
                out.reward += s.spec.rewards.success;
            }
        }
        if s.row.installed[..n].iter().all(|&b| b) {
            out.installed = true;
            out.terminated = true;
        } else if (0..n).any(|i| {
            let (p, v) = body_state(s, s.h.row[i]);
            fell(&s.spec, &p, v, held(s, i))
        }) {
            out.reward += s.spec.rewards.fail;
            out.fell = true;
            out.terminated = true;
        }
        if !s.held {
            let next = (0..n).find(|&i| !s.row.installed[i]).unwrap_or(n - 1);
            make_current(s, next);
        }
    }

    fn write_frame(&self, s: &State, f: &mut [f32]) {
        for (fi, qi) in f.iter_mut().zip(s.q) {
            *fi = qi as f32;
        }
        f[6] = if s.suction_on { 1.0 } else { -1.0 };
        let put = |f: &mut [f32], k: usize, v: Vector| f[k..k + 3].copy_from_slice(&[v.x, v.y, v.z]);
        let (cup, tile, target) =
            (s.tcp().translation, body_state(s, s.h.object).0.translation, s.target.translation);
        put(f, 7, cup);
        put(f, 10, target);
        put(f, 13, tile);
        put(f, REL, tile - cup);
        put(f, REL + 3, target - tile);
        for i in 0..MAX_ROW {
            let k = ROW_SLOTS + 7 * i;
            match s.h.row.get(i) {
                Some(&h) => {
                    put(f, k, s.row.targets[i]);
                    put(f, k + 3, body_state(s, h).0.translation);
                    f[k + 6] = if s.row.installed[i] { 1.0 } else { 0.0 };
                }
                None => f[k..k + 7].iter_mut().for_each(|v| *v = 0.0),
            }
        }
    }
}
