//! Each task's logic behind one trait, [`TaskLogic`], as ManiSkill splits its tasks: what an
//! episode start resets, what the end-effector command does, how success and failure are judged,
//! and the observation frame's layout. [`State`] is what every task reads and writes (the Rapier
//! world, the arm, the effector's state); the arm's motion, the physics step and the frame
//! stacking are the [`Env`](crate::Env)'s, the same for every task. Base frame, metres, radians.
//!
//! One module per task: [`suction`] (TileSuction), [`gripper`] (BlockGrip), [`screw`] (Screw),
//! [`tile_row`] (TileRow), [`tile_place`] (TilePlace).

pub(crate) mod gripper;
pub(crate) mod screw;
pub(crate) mod suction;
pub(crate) mod tile_place;
pub(crate) mod tile_row;

use crate::env::StepOutcome;
use crate::spec::{EffectorSpec, TaskSpec};
use crate::starts::Start;
use crate::world::Handles;
use crate::{CONTROL_DT, FRAME_STACK, SimError};
use rapier3d::prelude::*;
use std::sync::Arc;

/// The three tasks of the paper's three end effectors, and a row of tiles.
///
/// * `TileSuction` (paper §5.1, exact): UR3 with a four-cup suction head. Pick: the cup centre is
///   within 0.04 m of the tile's grasp point (centre of its top face) while the suction state is on
///   → the tile is held (rigidly, at its current offset) and +1 is paid once per episode.
///   Install: the tile's centre is within 0.03 m of the target (the centre of a tile lying on the
///   install pad) → +1, terminated. Install is measured whether or not the tile is still held
///   (paper: "the robot needs to carry the tile to the target position, and if the distance … is
///   less than 0.03 m, the task is finished"). Fall → −0.5, terminated: the tile leaves the table
///   (centre below `z = -0.02`), tilts more than 45°, or falls faster than 1 m/s (dropped from
///   more than ~5 cm). Nothing else is rewarded.
/// * `BlockGrip`: parallel gripper picks a 4 cm wooden cube and places it on the pad. Grasp
///   (closing fingers stop on the block) → +1 once; place: block released (not held) with its
///   centre within 0.02 m of the target → +1, terminated; block leaves the table → −0.5, terminated.
/// * `Screw`: grip the nut threaded on a fixed M12 bolt and spin it down [`SCREW_TURNS`](crate::SCREW_TURNS)
///   turns. Grip the nut → +1 once; turns ≥ `SCREW_TURNS` → +1, terminated; loosened more than
///   one turn (the nut leaves the bolt and drops) → −0.5, terminated.
/// * `TileRow` (issue 26 §2): TileSuction's arm, suction head, tile and thresholds, with three
///   tiles installed one after another on three pads in one episode, tile `i` on pad `i`. Each
///   tile's first pick +1 (a tile is picked as in TileSuction: the nearest grasp point within
///   0.04 m of the cup centre while the suction is on); each tile's install +1: the tile released
///   (not held) and resting (slower than 0.05 m/s) with its centre within 0.03 m of its pad's
///   target; an install is latched (paid once; the tile counts as installed even if it is
///   knocked off later). All three installed → terminated (the third install's +1 is paid in
///   that step, so a success sums to 6). Any tile falling (TileSuction's rules) → −0.5,
///   terminated. `StepOutcome::installed` marks the step the row is complete, not each tile's
///   install (each is a +1 and an observation flag). The module `task/tile_row.rs` says why.
/// * `TilePlace` (issue 46): TileSuction's arm, head, tile, pad and starts under rules a real
///   cell keeps. The held tile stays a dynamic body (it collides with the table, the pad and the
///   arm) held by a force-limited joint that exists only while a cup's lip is sealed on its face
///   (`[effector.seal]`); the first hold pays +1; placed (released, resting on the pad, centre
///   within 5 mm and yaw within 2° of the target) pays +1 and ends the episode; a fall −0.5.
///   `task/tile_place.rs` has the rules and the numbers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(into = "&'static str")]
pub enum Task {
    TileSuction,
    BlockGrip,
    Screw,
    TileRow,
    TilePlace,
}

impl Task {
    /// All tasks, in a fixed order (the paper's three first).
    pub const ALL: [Task; 5] =
        [Task::TileSuction, Task::BlockGrip, Task::Screw, Task::TileRow, Task::TilePlace];

    /// Parse "TileSuction"/"BlockGrip"/"Screw"/"TileRow"/"TilePlace" or
    /// "suction"/"grip"/"screw"/"row"/"place" (case-insensitive).
    pub fn from_name(name: &str) -> Result<Task, SimError> {
        match name.to_ascii_lowercase().as_str() {
            "tilesuction" | "suction" | "tile_suction" => Ok(Task::TileSuction),
            "blockgrip" | "grip" | "gripping" | "block_grip" => Ok(Task::BlockGrip),
            "screw" | "screwing" => Ok(Task::Screw),
            "tilerow" | "row" | "tile_row" => Ok(Task::TileRow),
            "tileplace" | "place" | "tile_place" => Ok(Task::TilePlace),
            _ => Err(SimError::UnknownTask(name.to_string())),
        }
    }

    /// Canonical name ("TileSuction", "BlockGrip", "Screw", "TileRow", "TilePlace").
    pub fn name(self) -> &'static str {
        match self {
            Task::TileSuction => "TileSuction",
            Task::BlockGrip => "BlockGrip",
            Task::Screw => "Screw",
            Task::TileRow => "TileRow",
            Task::TilePlace => "TilePlace",
        }
    }

    /// The built-in spec of this task (`crates/tile-sim/tasks/*.toml`).
    pub fn spec(self) -> Arc<TaskSpec> {
        TaskSpec::builtin(self)
    }

    /// The task's logic.
    pub(crate) fn logic(self) -> &'static dyn TaskLogic {
        match self {
            Task::TileSuction => &suction::Suction,
            Task::BlockGrip => &gripper::BlockGrip,
            Task::Screw => &screw::Screw,
            Task::TileRow => &tile_row::TileRow,
            Task::TilePlace => &tile_place::TilePlace,
        }
    }

    /// Floats per observation frame.
    ///
    /// * TileSuction (16): `q[6]` rad, `suction` (+1 on / −1 off), `cup_centre[3]` m,
    ///   `target[3]` m (tile-centre target), `tile_centre[3]` m.
    /// * BlockGrip (16): `q[6]`, `gripper_width` (m, 0 … 0.085, finger gap), `tcp[3]` (point
    ///   between the fingertips), `target[3]` (block-centre target), `block_centre[3]`.
    /// * Screw (18): `q[6]`, `gripper_width` (m), `spin` (+1 tighten / 0 stopped / −1 loosen),
    ///   `tcp[3]`, `target[3]` (the nut's fully tightened centre), `nut_centre[3]`, `turns`
    ///   (turns screwed so far, ≥ 0 down the bolt).
    /// * TileRow (43): TileSuction's 16 for the current tile (`q[6]`, `suction`,
    ///   `cup_centre[3]`, `target[3]` and `tile_centre[3]` of the tile held, else of the first
    ///   one not installed: `task/tile_row.rs`), `tile_centre − cup_centre[3]`, `target −
    ///   tile_centre[3]`, then for each of the three tiles `i` in row
    ///   order: `target_i[3]` m (tile `i`'s centre installed on pad `i`), `tile_centre_i[3]` m,
    ///   `installed_i` (1 installed / 0 not). A spec's row of two leaves the third tile's seven
    ///   floats zero.
    /// * TilePlace (32): TileSuction's 16, then `vacuum` (the vacuum switch: 0 … 1, the sealed
    ///   cups' share times the built-up vacuum), `tile_centre − cup_centre[3]`, `target −
    ///   tile_centre[3]`, `yaw_error` (rad, the target's yaw minus the tile's, wrapped to ±45° for
    ///   a square tile), `cos 4ψ, sin 4ψ` of the tile's yaw ψ and of the target's (a square tile's
    ///   yaw is known modulo 90°: 4ψ is what a camera sees), then the fine gauge:
    ///   `tanh((target − tile_centre) / 1 cm)[3]` and `tanh(yaw_error / 2°)` (a policy's
    ///   normaliser scales each float by its spread over whole episodes, decimetres for the
    ///   differences: the last millimetres of a placement would be noise without it).
    ///
    /// All positions in the Base frame.
    pub fn obs_frame_dim(self) -> usize {
        self.logic().obs_frame_dim()
    }

    /// `FRAME_STACK × obs_frame_dim`.
    pub fn obs_dim(self) -> usize {
        FRAME_STACK * self.obs_frame_dim()
    }

    /// 7 (6 joints + EE command; TileRow too) or 8 for Screw (+ spin).
    pub fn act_dim(self) -> usize {
        self.logic().act_dim()
    }
}

impl From<Task> for &'static str {
    fn from(t: Task) -> &'static str {
        t.name()
    }
}

/// What every task reads and writes: the world and the episode's arm and effector state.
pub(crate) struct State {
    /// The task's numbers.
    pub(crate) spec: Arc<TaskSpec>,
    /// The arm's kinematics (the spec's `robot.model`).
    pub(crate) arm: &'static ur3_kin::UrModel,
    pub(crate) world: PhysicsWorld,
    pub(crate) h: Handles,
    /// Joint angles, rad.
    pub(crate) q: [f64; 6],
    /// tool0 (flange) pose after this step's arm motion.
    pub(crate) tool0: Pose,
    pub(crate) suction_on: bool,
    pub(crate) held: bool,
    /// The held object's pose in tool0 (suction, BlockGrip).
    pub(crate) hold_offset: Pose,
    /// Finger gap, m (gripper tasks).
    pub(crate) width: f32,
    /// Spin command in effect (Screw): +1, 0, −1.
    pub(crate) spin: i8,
    /// Turns screwed (Screw).
    pub(crate) turns: f64,
    /// Picked ever this episode.
    pub(crate) picked: bool,
    pub(crate) start: Start,
    /// The target of the object `h.object` names (TileRow: the current tile's).
    pub(crate) target: Pose,
    /// TileRow's per-tile episode state (default for the other tasks).
    pub(crate) row: tile_row::RowState,
    /// TilePlace's seal and placing state (default for the other tasks).
    pub(crate) seal: tile_place::SealState,
    /// The lip-to-face gap (m, cup centre above the grasped face; negative: pressed in) when each
    /// hold of this episode began (the suction tasks).
    pub(crate) hold_gaps: Vec<f32>,
}

impl State {
    /// The end effector as an episode starts: suction off, no spin, no turns, the gripper's gap
    /// `width` (m; 0 for a suction head).
    pub(super) fn reset_effector(&mut self, width: f32) {
        self.suction_on = false;
        self.width = width;
        self.spin = 0;
        self.turns = 0.0;
    }

    /// The gripper's numbers: (finger half extents, finger z, max width, speed). Zeros for suction.
    pub(crate) fn gripper(&self) -> ([f32; 3], f32, f32, f32) {
        match &self.spec.effector {
            EffectorSpec::Gripper { finger_half_extents, finger_z, max_width, speed, .. } => {
                (*finger_half_extents, *finger_z, *max_width, *speed)
            }
            EffectorSpec::Suction { .. } => ([0.0; 3], 0.0, 0.0, 0.0),
        }
    }

    /// The TCP: the spec's `tcp_z` out along tool0's z axis.
    pub(crate) fn tcp(&self) -> Pose {
        self.tool0 * Pose::from_translation(Vector::new(0.0, 0.0, self.spec.tcp_z()))
    }

    pub(crate) fn object_pose(&self) -> Pose {
        self.world.bodies.get(self.h.object).map(|b| *b.position()).unwrap_or(Pose::IDENTITY)
    }

    /// The object's pose and linear velocity.
    pub(crate) fn object_state(&self) -> (Pose, Vector) {
        self.world
            .bodies
            .get(self.h.object)
            .map(|b| (*b.position(), b.linvel()))
            .unwrap_or((Pose::IDENTITY, Vector::ZERO))
    }

    /// Let go of the held object: it becomes dynamic at its current pose, moving with the
    /// velocity the grasp point has during this step's arm motion (angular velocity zero).
    pub(crate) fn release_object(&mut self) {
        let target = (self.tool0 * self.hold_offset).translation;
        self.set_object_kinematic(false);
        if let Some(b) = self.world.bodies.get_mut(self.h.object) {
            let v = (target - b.position().translation) / CONTROL_DT;
            b.set_linvel(v, true);
            b.set_angvel(Vector::ZERO, true);
        }
    }

    pub(crate) fn set_object_kinematic(&mut self, kinematic: bool) {
        if let Some(b) = self.world.bodies.get_mut(self.h.object) {
            let ty = if kinematic { RigidBodyType::KinematicPositionBased } else { RigidBodyType::Dynamic };
            b.set_body_type(ty, true);
        }
    }

    /// Hold the object rigidly at its current offset from tool0 (kinematic while held); pays
    /// `reward` the first time in the episode.
    pub(crate) fn grasp(&mut self, hold_offset: Pose, out: &mut StepOutcome, reward: f32) {
        self.held = true;
        self.hold_offset = hold_offset;
        self.set_object_kinematic(true);
        self.first_pick(out, reward);
    }

    /// Mark the episode picked, paying `reward` the first time.
    pub(crate) fn first_pick(&mut self, out: &mut StepOutcome, reward: f32) {
        if !self.picked {
            self.picked = true;
            out.reward += reward;
        }
    }

    /// Write the frame layout every task shares: `q[6]`, the effector's `state` floats, then the
    /// TCP, target and object centres (Base frame, m). Returns how many floats were written.
    pub(crate) fn write_frame(&self, state: &[f32], f: &mut [f32]) -> usize {
        let tcp = self.tcp().translation;
        let obj = self.object_pose().translation;
        let tgt = self.target.translation;
        for (fi, qi) in f.iter_mut().zip(self.q) {
            *fi = qi as f32;
        }
        f[6..6 + state.len()].copy_from_slice(state);
        let mut k = 6 + state.len();
        for v in [tcp, tgt, obj] {
            f[k] = v.x;
            f[k + 1] = v.y;
            f[k + 2] = v.z;
            k += 3;
        }
        k
    }
}

/// One task's logic: the hooks the [`Env`](crate::Env) calls. Each implementation is a unit
/// struct in its own module; the numbers it uses are the task's.
pub(crate) trait TaskLogic: Sync {
    /// Floats per observation frame (see [`Task::obs_frame_dim`]).
    fn obs_frame_dim(&self) -> usize;
    /// Action length: 6 joint motions, the end-effector command, and the task's extra commands.
    fn act_dim(&self) -> usize;
    /// Reset the effector's state at an episode start (suction off, fingers open, spin stopped);
    /// the world is new and the arm not placed yet.
    fn reset(&self, s: &mut State);
    /// The held object follows tool0 (false for a nut that rides its bolt).
    fn carries_object(&self) -> bool {
        true
    }
    /// The finger gap reported in a snapshot (0 for an effector without fingers).
    fn gripper_width(&self, s: &State) -> f64 {
        s.width as f64
    }
    /// Place the bodies that follow the arm or the task state (fingers, nut) after the arm moved;
    /// `teleport` also sets their current pose (a reset or a teleport, not a step).
    fn place_attached(&self, _s: &mut State, _teleport: bool) {}
    /// Apply the end-effector commands `action[6..]` (already validated) before the physics step.
    fn effector(&self, s: &mut State, action: &[f32], out: &mut StepOutcome);
    /// Judge success and failure after the physics step: rewards, `installed`, `fell`,
    /// `terminated` (and whatever episode state the judging latches, TileRow's installs).
    fn evaluate(&self, s: &mut State, out: &mut StepOutcome);
    /// Write the newest observation frame (`obs_frame_dim` floats).
    fn write_frame(&self, s: &State, f: &mut [f32]);
}
