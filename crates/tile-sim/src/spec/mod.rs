//! Task specs: one TOML file describes a task (the robot, the end effector, the object, the
//! target, where episodes start, thresholds, rewards, the episode length), read into a
//! [`TaskSpec`] and checked field by field ([`SpecError`] names the field, the value and why).
//! A spec serializes back to the same field names (Python gets it as a dict).
//! The three built-in tasks are the files in `crates/tile-sim/tasks/`, compiled in with
//! `include_str!` ([`TaskSpec::builtin`]), so nothing is read from disk at run time.
//!
//! Frames and units everywhere: the Base frame (the UR "Base", DH frame 0, Z up), metres, kg,
//! seconds; angles in radians except where a field's name ends in `_deg`. Effector geometry is
//! given in tool0 (the flange frame, z out of the flange). Half extents are half the full size.
//!
//! What a spec does not hold: the arm's link shapes (from the robot's DH table), the control rate
//! and physics substeps (crate constants; the joint step per action is a constant too unless
//! `robot.joint_step` sets it), and the observation layout (the task
//! logic's, [`crate::Task::obs_frame_dim`]). The task logic that judges an episode follows from
//! the effector: `suction` → TileSuction's (TileRow's with a `[row]`, TilePlace's with
//! `thresholds.rule = "placed"`), `gripper` → BlockGrip's, `gripper` with `spin_rate` → Screw's.

mod check;

pub use check::SpecError;

use crate::Task;
use serde::{Deserialize, Serialize};
use std::sync::{Arc, OnceLock};

/// The spec format version this simulator reads.
pub const SPEC_VERSION: u32 = 1;

/// A task, as a spec file describes it (see the module docs for frames and units).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TaskSpec {
    /// Format version: must be [`SPEC_VERSION`] (1).
    pub version: u32,
    /// The task's name (the gymnasium id is `mimicrete/<name>-v0`), e.g. `"TileSuction"`.
    pub name: String,
    /// What people read about the task: its sentence, its success's name, its gestures.
    pub about: AboutSpec,
    /// The arm.
    pub robot: RobotSpec,
    /// The table the arm's base stands on.
    pub table: TableSpec,
    /// The end effector on tool0.
    pub effector: EffectorSpec,
    /// The object the task moves.
    pub object: ObjectSpec,
    /// Where the object must end up.
    pub target: TargetSpec,
    /// Where episodes start.
    pub starts: StartsSpec,
    /// Distances and angles that decide a pick, a success and a failure.
    pub thresholds: ThresholdsSpec,
    /// The sparse rewards.
    pub rewards: RewardsSpec,
    /// Episode length.
    pub episode: EpisodeSpec,
    /// A row of objects and pads (optional; absent: one object, one pad, as every task before
    /// TileRow). With a suction effector it selects the TileRow logic ([`TaskSpec::task`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub row: Option<RowSpec>,
}

/// What people read about a task (the simulator itself reads none of it).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct AboutSpec {
    /// The task as one sentence: an exported data set's task text (LeRobot's `task`).
    pub instruction: String,
    /// What a success is called in results and on the page (`"installed"`, `"placed"`).
    pub success: String,
    /// The gesture classes a hand drives the effector with: `"grip"` (closing, opening, fixed:
    /// suction and gripper) or `"screw"` (the five closing/opening × tightening/loosening/fixed
    /// classes; the screwing effector, whose spin needs them).
    pub gestures: String,
}

/// The arm.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSpec {
    /// UR model name, as `ur3_kin` names it: one of the models the simulator has an arm for,
    /// `"ur3"`, `"ur3e"`, `"ur5e"`, `"ur10e"` ([`crate::arm::SIMULATED`]).
    pub model: String,
    /// Joint angles (rad) at every episode start, base to wrist 3.
    pub home_q: [f64; 6],
    /// How far the tool moves per metre the teleoperator's hand moves (the calibration's
    /// `scale`, ur3-kin's `hand::Calibration`); absent: the arm's [`workspace_scale`]
    /// (1 for the UR3 and UR3e), [`TaskSpec::hand_scale`]. Finite and > 0.
    ///
    /// [`workspace_scale`]: crate::workspace_scale
    #[serde(default, skip_serializing_if = "Option::is_none", serialize_with = "decimal")]
    pub hand_scale: Option<f32>,
    /// How far each joint moves per control step at full action, `|a_i| = 1` (rad per step of
    /// [`CONTROL_DT`](crate::CONTROL_DT) s): the env's `q_next = clamp(q + clip(a, −1, 1) ·
    /// joint_step, −π, π)`, and the step the scripted expert, the teleop session and demogen
    /// divide a joint change by to get an action ([`TaskSpec::joint_step`]). Absent:
    /// [`MAX_JOINT_STEP`](crate::MAX_JOINT_STEP) = 0.04 rad (1 rad/s), the step of every
    /// built-in task. Finite, > 0, and at most the arm's slowest rated joint speed
    /// (`ur3_kin::UrModel::joint_limits`) × `CONTROL_DT` (0.126 rad on the UR3 and UR5e, 0.084
    /// rad on the UR10e). The larger arms' TileSuction specs set it smaller, so that a full
    /// step moves the tool about as far as on the UR3 (`tasks/tile_suction_ur5e.toml`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_step: Option<f64>,
    /// What an action's first six numbers command ([`crate::action`]): `"joint"` (absent: the
    /// paper's, each joint's motion) or `"tool"` (the TCP's motion and turn in Base, as a UR's
    /// `servoL` commands the tool; the joints follow through the Jacobian, each still at most
    /// `joint_step` per step).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub action: Option<ActionSpace>,
    /// Tool space only: TCP motion (m) per step at full action; absent:
    /// [`TOOL_STEP`](crate::action::TOOL_STEP) = 0.01 m. Finite, > 0, at most 0.05 m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_step: Option<f64>,
    /// Tool space only: TCP turn (rad) per step at full action; absent:
    /// [`TOOL_TURN`](crate::action::TOOL_TURN) = 0.04 rad. Finite, > 0, at most 0.2 rad.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool_turn: Option<f64>,
    /// The cell's safety planes: the TCP must stay inside this box, `[[x, y, z] min, [x, y, z]
    /// max]` (Base frame, m). A step that leaves it is a protective stop, as a UR stops when its
    /// tool crosses a safety plane: the episode fails (`rewards.fail`). Absent: no limit. Each
    /// min below its max, and the TCP at `home_q` inside.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tcp_box: Option<[[f64; 3]; 2]>,
}

/// What an action's first six numbers command (`robot.action`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionSpace {
    /// Each joint's motion, `a[i] · joint_step` rad (the paper's).
    #[default]
    Joint,
    /// The TCP's motion `a[0..3] · tool_step` m and turn `a[3..6] · tool_turn` rad, in Base.
    Tool,
}

/// The table: a fixed box whose top face is the plane `z = top_z`, centred under the base.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    /// Half extents (m): x, y, thickness / 2.
    #[serde(serialize_with = "decimal")]
    pub half_extents: [f32; 3],
    /// Height of the top face (m, Base frame; the UR base stands on it).
    #[serde(serialize_with = "decimal")]
    pub top_z: f32,
    /// Coulomb friction coefficient of the top.
    #[serde(serialize_with = "decimal")]
    pub friction: f32,
}

/// The end effector on tool0, by kind.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum EffectorSpec {
    /// A suction plate with four cups at `(±cup_offset, ±cup_offset)` (tool0), each a cylinder
    /// from the plate's face (tool0 z = 2 · plate_half_extents.z) to the cup lips at `tcp_z`.
    Suction {
        /// Plate half extents (m); the plate's centre is at tool0 z = `plate_half_extents[2]`.
        #[serde(serialize_with = "decimal")]
        plate_half_extents: [f32; 3],
        /// Cup centre offset from the flange axis along tool0 x and y (m).
        #[serde(serialize_with = "decimal")]
        cup_offset: f32,
        /// Cup radius (m).
        #[serde(serialize_with = "decimal")]
        cup_radius: f32,
        /// The TCP, the centre of the four cup lips, along tool0 z (m).
        #[serde(serialize_with = "decimal")]
        tcp_z: f32,
        /// How the cups hold a tile under the placed rule (`thresholds.rule = "placed"`, the
        /// TilePlace logic): a seal per cup and a force-limited hold. Absent: the paper's rigid
        /// hold within `thresholds.pick_dist`.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        seal: Option<SealSpec>,
    },
    /// A parallel gripper: a body box and two finger boxes sliding along tool0 y, closing and
    /// opening at a constant speed; with `spin_rate`, the screwing effector (it turns what it grips).
    Gripper {
        /// Body half extents (m); the body's centre is at tool0 z = `body_half_extents[2]`.
        #[serde(serialize_with = "decimal")]
        body_half_extents: [f32; 3],
        /// Finger half extents (m), tool0 axes.
        #[serde(serialize_with = "decimal")]
        finger_half_extents: [f32; 3],
        /// The fingers' centre along tool0 z (m); the TCP (between the fingertips) is here too.
        #[serde(serialize_with = "decimal")]
        finger_z: f32,
        /// Largest finger gap (m); the gap at an episode start.
        #[serde(serialize_with = "decimal")]
        max_width: f32,
        /// Closing and opening speed of the gap (m/s).
        #[serde(serialize_with = "decimal")]
        speed: f32,
        /// Friction coefficient of the fingers.
        #[serde(serialize_with = "decimal")]
        finger_friction: f32,
        /// Screwing: turns per second while spinning (absent: no spin command).
        #[serde(default, serialize_with = "decimal")]
        spin_rate: Option<f32>,
    },
}

/// A suction head's seal and holding force (`[effector.seal]`, the TilePlace logic,
/// `task/tile_place.rs`). A cup seals when its lip lies on the tile's face: the lip centre within
/// `gap` of the face plane (either side: a lip pressed in counts), the whole lip on the face, and
/// the cup's axis within `angle_deg` of the face normal (a lip pushed into the face by up to
/// `stroke` more stays on it: the cup's spring mount gives). While the suction is on and a cup
/// stays sealed the vacuum builds up over `time`; the hold's force limits are then
/// `vacuum_kpa · π · cup_radius² · sealed cups / safety_factor` along the cups' axis (peel),
/// `lip_friction` times that across it (shear), and that force times `cup_offset` as a torque.
/// Defaults of the built-in spec: a Ø30 mm flat cup at −60 kPa (≈ 42 N in theory per cup,
/// Schmalz's design guide), safety factor 1.5 (smooth dense parts), lip friction 0.5 (glazed
/// ceramic, dry).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SealSpec {
    /// Largest distance (m) between a cup's lip and the face for it to seal (and stay sealed).
    #[serde(serialize_with = "decimal")]
    pub gap: f32,
    /// Largest angle (degrees) between a cup's axis and the face normal for it to seal.
    #[serde(serialize_with = "decimal")]
    pub angle_deg: f32,
    /// Relative vacuum (kPa below ambient) once the seal is built up.
    #[serde(serialize_with = "decimal")]
    pub vacuum_kpa: f32,
    /// Seconds from the first sealed step to the full vacuum (the force ramps up linearly).
    #[serde(serialize_with = "decimal")]
    pub time: f32,
    /// Holding force divisor (≥ 1).
    #[serde(serialize_with = "decimal")]
    pub safety_factor: f32,
    /// Friction coefficient of the lips on the face: the shear limit over the peel limit.
    #[serde(serialize_with = "decimal")]
    pub lip_friction: f32,
    /// Travel (m) of the cups' spring mounts (level compensators; absent: 0, rigid cups):
    /// pressed onto a face that does not give, a cup's lip stays on it (sealed) while its mount
    /// gives, as far as `gap + stroke` below the face; pressed further, the arm stops.
    #[serde(default, serialize_with = "decimal")]
    pub stroke: f32,
}

impl SealSpec {
    /// How far (m) a lip may be pressed below the face and stay on it: `gap + stroke`.
    pub fn give(&self) -> f32 {
        self.gap + self.stroke
    }
}

/// The object the task moves.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Its name in the scene (`"tile"`, `"block"`, `"nut"`).
    pub name: String,
    /// `"box"` (with `half_extents`) or `"cylinder"` (with `radius`, `half_height`; axis along z).
    pub shape: String,
    /// Box half extents (m), the object's own axes (z up when it lies flat).
    #[serde(default, serialize_with = "decimal")]
    pub half_extents: Option<[f32; 3]>,
    /// Cylinder radius (m).
    #[serde(default, serialize_with = "decimal")]
    pub radius: Option<f32>,
    /// Cylinder half height (m).
    #[serde(default, serialize_with = "decimal")]
    pub half_height: Option<f32>,
    /// Mass (kg); absent: Rapier's default density (a kinematic object, the nut).
    #[serde(default, serialize_with = "decimal")]
    pub mass: Option<f32>,
    /// Friction coefficient; absent: Rapier's default (0.5).
    #[serde(default, serialize_with = "decimal")]
    pub friction: Option<f32>,
    /// Colour in the scene, RGBA in [0, 1].
    #[serde(serialize_with = "decimal")]
    pub rgba: [f32; 4],
}

/// Where the object must end up, by kind.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum TargetSpec {
    /// A fixed box pad on the table; the target is the object's centre resting on its top, at
    /// the pad's centre (moved with a start's target offset).
    Pad {
        /// The pad's centre (x, y) on the table (m, Base frame), before a start's offset.
        #[serde(serialize_with = "decimal")]
        xy: [f32; 2],
        /// Pad half extents (m).
        #[serde(serialize_with = "decimal")]
        half_extents: [f32; 3],
        /// Friction coefficient of the pad's top.
        #[serde(serialize_with = "decimal")]
        friction: f32,
    },
    /// A bolt standing on a plate at the object's start (x, y); the nut starts caught on the thread
    /// and the target is its centre `turns` turns further down.
    Bolt {
        /// Plate half extents (m); the plate lies on the table.
        #[serde(serialize_with = "decimal")]
        plate_half_extents: [f32; 3],
        /// Bolt radius (m).
        #[serde(serialize_with = "decimal")]
        radius: f32,
        /// Height of the bolt's top above the table (m).
        #[serde(serialize_with = "decimal")]
        top_z: f32,
        /// Thread pitch (m per turn).
        #[serde(serialize_with = "decimal")]
        pitch: f32,
        /// The nut's top sits this far below the bolt's top when it has just caught the thread (m).
        #[serde(serialize_with = "decimal")]
        catch_gap: f32,
        /// Turns to screw down for success.
        turns: f64,
    },
}

/// Where episodes start: the paper's distribution (demos are recorded there) and the wide one.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct StartsSpec {
    /// The paper's starts (paper §5.1: the object's x uniform in [0, 0.15] m).
    pub paper: VariationSpec,
    /// The wide starts (the object spread over the table within reach, turned, the target moved).
    pub wide: VariationSpec,
}

/// One start distribution; each range is `[lo, hi]`, a range with `lo == hi` is not drawn from.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct VariationSpec {
    /// The object centre's x (m, Base frame), uniform in the range.
    #[serde(serialize_with = "decimal")]
    pub object_x: [f32; 2],
    /// The object centre's y (m).
    #[serde(serialize_with = "decimal")]
    pub object_y: [f32; 2],
    /// The object's yaw about Base z (degrees).
    #[serde(serialize_with = "decimal")]
    pub yaw_deg: [f32; 2],
    /// The target moves by (dx, dy), each uniform in `[-target_jitter, target_jitter]` (m).
    #[serde(serialize_with = "decimal")]
    pub target_jitter: f32,
    /// The pad moves with the target (else it stays).
    pub pad_follows: bool,
    /// The pad's yaw about its centre (degrees), turning the target with it; absent: square.
    /// A single pad only (not a row's, not a bolt's plate).
    #[serde(default, skip_serializing_if = "Option::is_none", serialize_with = "decimal")]
    pub pad_yaw_deg: Option<[f32; 2]>,
}

/// Thresholds; each task logic requires the ones it reads (see [`SpecError`]).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ThresholdsSpec {
    /// Suction: the cup centre within this distance of the grasp point (the centre of the
    /// object's upper face) picks it (m).
    #[serde(default, serialize_with = "decimal")]
    pub pick_dist: Option<f32>,
    /// Success: the object's centre within this distance of the target (m); the gripper logic
    /// also needs the object released.
    #[serde(default, serialize_with = "decimal")]
    pub success_dist: Option<f32>,
    /// Failure: the object's centre below this height (m).
    #[serde(default, serialize_with = "decimal")]
    pub fall_z: Option<f32>,
    /// Failure: the object, not held, falling faster than this (m/s).
    #[serde(default, serialize_with = "decimal")]
    pub fall_speed: Option<f32>,
    /// Failure (suction): the object, not held, tilted so far that its up axis' z is below this
    /// cosine (0.7071… = 45°).
    #[serde(default, serialize_with = "decimal")]
    pub fall_tilt_cos: Option<f32>,
    /// Screw: the flange's z must point down within this cosine of the bolt axis (0.94 ≈ 20°)
    /// to grip and turn the nut.
    #[serde(default, serialize_with = "decimal")]
    pub align_cos: Option<f32>,
    /// Screw: the fingers slip off the nut when the TCP moves farther than this from it (m).
    #[serde(default, serialize_with = "decimal")]
    pub slip_dist: Option<f32>,
    /// Screw: failure when the nut is loosened more than this many turns (it leaves the bolt).
    #[serde(default)]
    pub fail_turns: Option<f64>,
    /// The success rule: `"paper"` (absent: the paper's, the tile's centre within
    /// `success_dist` of the target, held or not) or `"placed"` (the TilePlace logic, which also
    /// needs `[effector.seal]`): released no higher than `release_height` above its resting
    /// height, then resting (slower than `rest_speed` for `rest_steps` steps, its centre within
    /// `rest_height` of the target's height), the centre within `success_dist` of the target in
    /// x and y and its yaw within `success_yaw_deg` of the target's (a square tile: modulo 90°).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rule: Option<Rule>,
    /// Placed: the yaw tolerance (degrees).
    #[serde(default, skip_serializing_if = "Option::is_none", serialize_with = "decimal")]
    pub success_yaw_deg: Option<f32>,
    /// Placed: a tile let go more than this (m) above its resting height was dropped, not set down.
    #[serde(default, skip_serializing_if = "Option::is_none", serialize_with = "decimal")]
    pub release_height: Option<f32>,
    /// Placed: the resting tile's centre within this (m) of the target's height (on the pad,
    /// not tilted on an edge, not pushed into it).
    #[serde(default, skip_serializing_if = "Option::is_none", serialize_with = "decimal")]
    pub rest_height: Option<f32>,
    /// Placed: resting means slower than this (m/s) ...
    #[serde(default, skip_serializing_if = "Option::is_none", serialize_with = "decimal")]
    pub rest_speed: Option<f32>,
    /// ... for this many steps in a row.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rest_steps: Option<u32>,
}

/// A success rule ([`ThresholdsSpec::rule`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rule {
    /// The paper's: proximity, held or not, any yaw (with the paper's rigid hold).
    Paper,
    /// Placed as a tiler means it (with the contact hold of `[effector.seal]`).
    Placed,
}

/// The sparse rewards (each paid at the event, the pick only once per episode).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RewardsSpec {
    /// The first pick / grasp of the episode.
    #[serde(serialize_with = "decimal")]
    pub pick: f32,
    /// Success (installed, placed, tightened); ends the episode.
    #[serde(serialize_with = "decimal")]
    pub success: f32,
    /// Failure (fell, spun off); ends the episode. Usually negative.
    #[serde(serialize_with = "decimal")]
    pub fail: f32,
}

/// Episode length.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EpisodeSpec {
    /// Episodes are truncated (not terminated) after this many env steps.
    pub max_steps: u32,
}

/// A row: `count` copies of the object and of the pad, object `i` belonging on pad `i` (TileRow,
/// `crate::Task::TileRow`). A start places the row as it places the one object: object `i`'s
/// centre is the start's object centre plus `i · object_pitch`, with the start's yaw (each object
/// turned about its own centre, the row's line not turned); pad `i` and its target are the pad's
/// and the target's (with the start's offsets) plus `i · pad_pitch`. Pitches are in the Base
/// frame's (x, y), m. Object 0 and pad 0 are where `starts` and `target.xy` put the one object
/// and the one pad of the other tasks, so a row of one is TileSuction's scene.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RowSpec {
    /// How many objects and pads: 2 to [`MAX_ROW`].
    pub count: usize,
    /// From one object's start centre to the next one's (m, Base x and y). Consecutive objects
    /// must not overlap at any yaw of the starts (checked with every start).
    #[serde(serialize_with = "decimal")]
    pub object_pitch: [f32; 2],
    /// From one pad's centre (and target) to the next one's (m, Base x and y). Consecutive pads
    /// may touch, not overlap.
    #[serde(serialize_with = "decimal")]
    pub pad_pitch: [f32; 2],
    /// The row is laid in its order: object `i` may be picked only once objects `0..i` are
    /// installed. A pick of an object whose turn has not come is a failure (`rewards.fail`, the
    /// episode ends; the object is not gripped). Off (the default), any object may be picked at
    /// any time.
    #[serde(default)]
    pub in_order: bool,
}

/// The longest row a spec may have (objects and pads): TileRow's observation frame has a slot
/// for each of this many tiles (a task's frame length is fixed, [`crate::Task::obs_frame_dim`]).
pub const MAX_ROW: usize = 3;

/// Numbers that serialize as the decimals they were written as (an `f32` 0.04 as 0.04, not
/// 0.03999999910593033), so a spec read back (a Python dict) shows the file's values.
trait Decimal {
    fn decimal<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error>;
}

fn shortest(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(x as f64)
}

impl Decimal for f32 {
    fn decimal<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(shortest(*self))
    }
}

impl<const N: usize> Decimal for [f32; N] {
    fn decimal<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.map(shortest).serialize(s)
    }
}

impl<T: Decimal> Decimal for Option<T> {
    fn decimal<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Some(v) => s.serialize_some(&Dec(v)),
            None => s.serialize_none(),
        }
    }
}

struct Dec<'a, T>(&'a T);

impl<T: Decimal> Serialize for Dec<'_, T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.decimal(s)
    }
}

fn decimal<T: Decimal, S: serde::Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
    v.decimal(s)
}

/// The built-in spec files, in [`Task::ALL`] order.
const BUILTIN_TOML: [(&str, &str); 5] = [
    ("tile_suction.toml", include_str!("../../tasks/tile_suction.toml")),
    ("block_grip.toml", include_str!("../../tasks/block_grip.toml")),
    ("screw.toml", include_str!("../../tasks/screw.toml")),
    ("tile_row.toml", include_str!("../../tasks/tile_row.toml")),
    ("tile_place.toml", include_str!("../../tasks/tile_place.toml")),
];

impl TaskSpec {
    /// Read and check a spec from TOML text; `source` names it in errors (a file name).
    ///
    /// # Errors
    /// [`SpecError`]: the text is not TOML or not a spec (an unknown or missing field, a wrong
    /// type), or a field's value is out of range or does not fit the effector's task logic.
    pub fn from_toml(text: &str, source: &str) -> Result<TaskSpec, SpecError> {
        let spec: TaskSpec = toml::from_str(text).map_err(|e| SpecError::parse(source, text, &e))?;
        spec.check()?;
        Ok(spec)
    }

    /// Read and check a spec file.
    ///
    /// # Errors
    /// [`SpecError::Io`] when the file cannot be read, else as [`TaskSpec::from_toml`].
    pub fn from_file(path: &std::path::Path) -> Result<TaskSpec, SpecError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| SpecError::Io { path: path.display().to_string(), reason: e.to_string() })?;
        TaskSpec::from_toml(&text, &path.display().to_string())
    }

    /// The built-in spec of `task` (parsed once, shared).
    pub fn builtin(task: Task) -> Arc<TaskSpec> {
        static SPECS: OnceLock<[Arc<TaskSpec>; 5]> = OnceLock::new();
        let specs = SPECS.get_or_init(|| {
            BUILTIN_TOML.map(|(name, text)| {
                Arc::new(TaskSpec::from_toml(text, name).expect("invariant: the built-in specs are valid"))
            })
        });
        let i = Task::ALL.iter().position(|t| *t == task).expect("invariant: Task::ALL lists every task");
        Arc::clone(&specs[i])
    }

    /// The built-in spec file's text of `task` (what [`TaskSpec::builtin`] parses).
    pub fn builtin_toml(task: Task) -> &'static str {
        let i = Task::ALL.iter().position(|t| *t == task).expect("invariant: Task::ALL lists every task");
        BUILTIN_TOML[i].1
    }

    /// The task logic this spec's effector selects.
    pub fn task(&self) -> Task {
        match self.effector {
            EffectorSpec::Suction { .. } if self.row.is_some() => Task::TileRow,
            EffectorSpec::Suction { .. } if self.thresholds.rule == Some(Rule::Placed) => Task::TilePlace,
            EffectorSpec::Suction { .. } => Task::TileSuction,
            EffectorSpec::Gripper { spin_rate: None, .. } => Task::BlockGrip,
            EffectorSpec::Gripper { spin_rate: Some(_), .. } => Task::Screw,
        }
    }

    /// The TCP's offset along tool0 z (m): the cup lips or the point between the fingertips.
    pub fn tcp_z(&self) -> f32 {
        match self.effector {
            EffectorSpec::Suction { tcp_z, .. } => tcp_z,
            EffectorSpec::Gripper { finger_z, .. } => finger_z,
        }
    }

    /// The arm's kinematics: `robot.model` as `ur3_kin` knows it (a checked spec names one of
    /// the models the simulator has an arm for, [`crate::arm::SIMULATED`]; an unknown name, in a
    /// spec that was never checked, gives the UR3).
    pub fn arm(&self) -> &'static ur3_kin::UrModel {
        ur3_kin::UrModel::by_name(&self.robot.model).unwrap_or(&ur3_kin::UR3)
    }

    /// The hand → robot scale of live teleoperation with this spec: `robot.hand_scale` if the
    /// spec sets it, else the arm's [`workspace_scale`](crate::workspace_scale) (its |a2| + |a3|
    /// over the UR3's: 1 for the UR3 and UR3e, about 1.79 for the UR5e, 2.59 for the UR10e), so
    /// a person's hand moving the UR3-size distances moves the larger arm's tool across its
    /// larger workspace.
    pub fn hand_scale(&self) -> f32 {
        self.robot.hand_scale.unwrap_or_else(|| crate::starts::workspace_scale(self.arm()))
    }

    /// Joint motion (rad) per control step at `|a| = 1`: `robot.joint_step` if the spec sets
    /// it, else [`MAX_JOINT_STEP`](crate::MAX_JOINT_STEP) (0.04 rad, 1 rad/s).
    pub fn joint_step(&self) -> f64 {
        self.robot.joint_step.unwrap_or(crate::MAX_JOINT_STEP)
    }

    /// What an action's first six numbers command: `robot.action`, else joint motions.
    pub fn action_space(&self) -> ActionSpace {
        self.robot.action.unwrap_or_default()
    }

    /// TCP motion (m) per step at full action in the tool space: `robot.tool_step`, else
    /// [`TOOL_STEP`](crate::action::TOOL_STEP).
    pub fn tool_step(&self) -> f64 {
        self.robot.tool_step.unwrap_or(crate::action::TOOL_STEP)
    }

    /// TCP turn (rad) per step at full action in the tool space: `robot.tool_turn`, else
    /// [`TOOL_TURN`](crate::action::TOOL_TURN).
    pub fn tool_turn(&self) -> f64 {
        self.robot.tool_turn.unwrap_or(crate::action::TOOL_TURN)
    }

    /// Objects (and pads) in the task: the row's `count`, else 1.
    pub fn row_len(&self) -> usize {
        self.row.map_or(1, |r| r.count)
    }

    /// Object `i`'s offset in a row from object 0 (m, Base x and y; zero for `i = 0` and without
    /// a row).
    pub fn object_offset(&self, i: usize) -> [f32; 2] {
        self.row.map_or([0.0; 2], |r| [i as f32 * r.object_pitch[0], i as f32 * r.object_pitch[1]])
    }

    /// Pad `i`'s (and target `i`'s) offset in a row from pad 0 (m; zero for `i = 0` and without a
    /// row).
    pub fn pad_offset(&self, i: usize) -> [f32; 2] {
        self.row.map_or([0.0; 2], |r| [i as f32 * r.pad_pitch[0], i as f32 * r.pad_pitch[1]])
    }

    /// The suction head's seal (`[effector.seal]`), if it has one.
    pub fn seal(&self) -> Option<&SealSpec> {
        match &self.effector {
            EffectorSpec::Suction { seal, .. } => seal.as_ref(),
            EffectorSpec::Gripper { .. } => None,
        }
    }

    /// Half the object's height (m): its centre's height above the surface it rests on.
    pub fn object_half_height(&self) -> f32 {
        self.object.half_extents.map(|h| h[2]).or(self.object.half_height).unwrap_or(0.0)
    }
}

impl VariationSpec {
    /// As the [`Variation`](crate::Variation) that draws the starts (yaw in radians).
    pub fn variation(&self) -> crate::Variation {
        crate::Variation {
            object_x: self.object_x,
            object_y: self.object_y,
            yaw: [self.yaw_deg[0].to_radians(), self.yaw_deg[1].to_radians()],
            target_jitter: self.target_jitter,
            pad_follows: self.pad_follows,
            pad_yaw: self.pad_yaw_deg.map_or([0.0; 2], |[lo, hi]| [lo.to_radians(), hi.to_radians()]),
        }
    }
}
