//! tile-sim: Rapier worlds for the UR3 construction tasks of Duan & Zou (suction tile
//! installation, block gripping, nut screwing), frame-stacked observations, sparse rewards, a
//! batched multi-threaded [`VecEnv`] and a scripted joint-space [`expert`].
//!
//! # Frames and units
//! World frame = the UR "Base" frame (DH frame 0): Z up, metres, radians, seconds. The UR3 base
//! stands on the table top, which is the plane `z = 0`. Quaternions are `[x, y, z, w]`.
//!
//! # Control rate, joint step, physics substeps (chosen, measured)
//! * One env step = [`CONTROL_DT`] = 0.04 s of simulated time (25 Hz control), simulated by one
//!   Rapier step with `dt = CONTROL_DT` and [`PHYSICS_SUBSTEPS`] = 2 solver substeps (20 ms each; 1, 2 and 4 substeps were measured at
//!   35k, 37k and 41k instructions per TileSuction step: two keep resting and pushed contacts stable).
//!   A TilePlace world runs [`world::PLACE_SUBSTEPS`] = 8 (a released tile landing on the pad needs
//!   them; `world::physics_substeps`).
//! * At `|a_i| = 1` a joint moves [`MAX_JOINT_STEP`] = 0.04 rad per step, i.e. 1 rad/s (the UR3's
//!   rated joint speed is 3.14 rad/s; 1 rad/s keeps the flange under ~0.5 m/s, a safe teaching speed).
//!   A move of 1 rad takes 25 steps (1 s); an episode of [`MAX_EPISODE_STEPS`] = 750 steps lasts 30 s.
//!   That is the default: a task spec's `robot.joint_step` sets another step ([`TaskSpec::joint_step`];
//!   the UR5e and UR10e TileSuction specs scale it down by their layout's scale).
//! * The arm links are `kinematic_position_based` bodies placed by `ur3_kin::fk_all` each step, so
//!   the arm cannot be pushed, but it pushes (and can knock over, sweep off, or crush) the object.
//! * Idle steps skip the solver: when every dynamic body (the object, or each tile of a row) is
//!   held/kinematic, or asleep with every arm collider (swept over the step) more than 2 cm from
//!   it, the kinematic bodies are placed directly and `PhysicsWorld::step` is not called (Rapier
//!   would not move anything either; a sleeping object is woken as soon as the arm comes within
//!   2 cm, in every mode). `Env::set_skip_idle_physics(false)` turns this off; a test checks that expert
//!   episodes end identically either way.
//! * Measured on this 2-core VM (`cargo bench -p tile-sim --bench vecenv`, shared with other
//!   engineers' builds at load average 3–5, so figures vary ±50 %): a TileSuction step that runs
//!   the solver (FK + Rapier + rewards + frame stacking) is ~37k instructions (callgrind) ≈ 6–8 µs;
//!   VecEnv(64) with uniform random actions, where most steps are idle (`cargo bench -p tile-sim
//!   --bench vecenv -- 64 3`, commit ad106f1, 2026-12-01, this 2-core AMD EPYC VM at load
//!   average 7), in env-steps/s with 1 / 2 threads: TileSuction 28k / 128k (solver skipped on
//!   90 % of steps), BlockGrip 62k / 108k (91 %), Screw 532k / 843k (100 %); under that load the
//!   figures are only good to a factor of two. `VecEnv` keeps `num_threads − 1` persistent workers and
//!   hands out blocks of 4 envs dynamically, so a starved thread never stalls a step call.
//!
//! # Scene layout (Base frame)
//! * Table top `z = 0`, 1.4 m × 1.4 m, friction 0.6; the UR3 base at the origin.
//! * Tile: glazed ceramic 0.15 × 0.15 × 0.01 m, 0.5 kg, friction 0.6, lying flat with its centre at
//!   `(x, 0.32, 0.005)`, `x ~ U[0, 0.15]` per episode (paper §5.1). Grasp point: top-face centre.
//! * Install pad: fixed 0.2 × 0.2 × 0.04 m box centred at `(−0.22, 0.28)`; target = the centre of
//!   a tile lying on it, `(−0.22, 0.28, 0.045)`. Tile and target are 0.32–0.36 m from the base axis,
//!   well inside the UR3's 0.5 m reach with the flange pointing down.
//! * Episode start: joints [`HOME_Q`] (flange down, cup centre 0.2 m above the table).
//! * Suction head on tool0: 0.1 × 0.1 × 0.02 m plate and four cups (radius 15 mm) at
//!   `(±0.045, ±0.045)` spanning tool-z 0.02–0.05 m; the cup centre (TCP) is tool0 + 0.05 m along z.
//!   A picked tile is held rigidly at the offset it had when picked (kinematic while held).
//! * Gripper on tool0: body 0.06 × 0.11 × 0.06 m, two fingers sliding along tool-y, TCP at tool0 +
//!   0.085 m; gap 0–0.085 m at a constant 0.1 m/s. Block: 4 cm wooden cube (45 g).
//! * Screw: M12 bolt (pitch 1.75 mm) on a plate at `(x, 0.32)`, `x ~ U[0, 0.15]`; the nut rides the
//!   thread (kinematic), spun at 1 turn/s while gripped with the flange within ~20° of vertical.
//! * TilePlace: TileSuction's scene; the held tile stays dynamic, held by a force-limited joint
//!   while a cup is sealed on its face (`src/task/tile_place.rs`); the wide starts turn the pad.
//! * TileRow: three TileSuction tiles in a row along x at `y = 0.40` (tile 0's centre at
//!   `x ~ U[−0.20, −0.14]`, 0.17 m between centres) and three touching pads in a row along x at
//!   `y = 0.18` (centres at x = −0.2, 0, 0.2); tile `i` goes on pad `i`
//!   (`tasks/tile_row.toml` explains the layout).
//!
//! # Action (f32, length [`Task::act_dim`])
//! `a[0..6]` ∈ [-1, 1]: joint motion, `q_next = clamp(q + clip(a, -1, 1)·joint_step, -π, π)`
//! (`joint_step`: the spec's [`TaskSpec::joint_step`], [`MAX_JOINT_STEP`] unless it sets one;
//! clamped, not wrapped: the arm never jumps across ±π). A spec with `robot.action = "tool"`
//! (TilePlace) reads them as the TCP's motion and turn instead ([`action`]). `a[6]`: end-effector command,
//! `≥ 0.5` → suction on / gripper close, `≤ -0.5` → drop / open, otherwise fixed (hold the state).
//! Screw has `a[7]` = spin: `≥ 0.5` tighten, `≤ -0.5` loosen, otherwise stopped.
//! A recorded human demonstration produces exactly this: joint part
//! `clip((q_ik − q)/joint_step, −1, 1)`, command ∈ {−1, 0, +1}. Values out of range are
//! clipped; NaN/∞ is a [`SimError`].
//!
//! # Observation
//! [`FRAME_STACK`] frames of [`Task::obs_frame_dim`] floats, **oldest first, newest last**; at the
//! start of an episode the missing older frames are zeros. Frame layouts are documented on
//! [`Task::obs_frame_dim`].
//!
//! # Rewards (sparse, paper §5.1 for TileSuction)
//! See [`Task`] for each task's rewards and termination rules.
//!
//! # Tasks as data
//! Each task's numbers (robot, effector geometry, object, target, start distributions,
//! thresholds, rewards, episode length) are a [`TaskSpec`], read from a versioned TOML file: the
//! built-in four are `crates/tile-sim/tasks/{tile_suction,block_grip,screw,tile_row}.toml`, compiled in
//! ([`TaskSpec::builtin`], [`Task::spec`]); [`Env::from_spec`] runs another. Each task's logic
//! (effector, success and failure, frame layout) is a module behind one trait (`src/task/`).
//! The files sit in the crate, not at the repository's top, because the crate compiles them in
//! and owns what they mean (`cargo package` only ships what is inside the crate).

pub mod action;
pub mod arm;
mod env;
pub mod expert;
mod owned;
mod pool;
pub mod spec;
mod starts;
mod task;
mod vecenv;
pub mod world;

pub use env::{Env, HOME_Q, Placement, PoseRec, Snapshot, StepOutcome, episode_scene, object_start};
pub use owned::{RecordState, StepInfo};
pub use spec::{SPEC_VERSION, SpecError, TaskSpec};
pub use starts::{
    MAX_TARGET_OFFSET, MAX_YAW, PAD_CLEARANCE, REACH_MARGIN, Start, Variation, workspace_scale,
};
pub use task::Task;
pub use task::gripper::PLACE_DIST;
pub use task::suction::{FALL_SPEED, FALL_Z, INSTALL_DIST, PICK_DIST};
pub use task::tile_row::{REST_SPEED, RowTile};
pub use vecenv::{StepBuffers, StepOut, VecEnv, VecEnvState, episode_seed};
pub use world::{Scene, SceneFrame, SceneItem, Shape};

/// Frames stacked into one observation (paper §5.1: five, zero-padded at episode start).
pub const FRAME_STACK: usize = 5;
/// Episodes are truncated (not terminated) after this many env steps (paper §5.1).
pub const MAX_EPISODE_STEPS: u32 = 750;
/// Simulated seconds per env step (25 Hz control). One Rapier step of this `dt` per env step.
pub const CONTROL_DT: f32 = 0.04;
/// Rapier solver substeps inside one env step (`IntegrationParameters::num_solver_iterations`).
pub const PHYSICS_SUBSTEPS: usize = 2;
/// Joint motion in radians per env step at `|a| = 1` (1 rad/s at [`CONTROL_DT`]): the default of
/// a spec's `robot.joint_step` ([`TaskSpec::joint_step`]), the step of every built-in task.
pub const MAX_JOINT_STEP: f64 = 0.04;

/// Errors of the simulator (bad inputs; the state is left unchanged when one is returned).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// The action slice has the wrong length.
    #[error("action has length {got}, expected {expected} (act_dim of {task})")]
    ActionShape { expected: usize, got: usize, task: &'static str },
    /// An action component is NaN or infinite.
    #[error("action component {index} is not finite ({value})")]
    NonFiniteAction { index: usize, value: f32 },
    /// An output buffer has the wrong length.
    #[error("{what} buffer has length {got}, expected {expected}")]
    BufferShape { what: &'static str, expected: usize, got: usize },
    /// `step` was called on an episode that has already terminated or been truncated.
    #[error("the episode has ended (terminated or truncated): call reset before step")]
    EpisodeOver,
    /// An unknown task name.
    #[error(
        "unknown task {0:?}: expected TileSuction, BlockGrip, Screw or TileRow (or suction, grip, screw, row)"
    )]
    UnknownTask(String),
    /// A state set through `set_*` is invalid (non-finite numbers, bad sizes).
    #[error("invalid state: {0}")]
    InvalidState(String),
    /// A `VecEnv` argument is invalid (zero envs, mask length, ...).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}

/// Turns of the nut needed to complete the Screw task.
pub const SCREW_TURNS: f64 = 3.0;

/// The simulator's constants in one record (serialized with the upper-case names of the
/// constants, plus `tasks`: per-task `obs_frame_dim`, `obs_dim`, `act_dim`). `f32` constants are
/// given as the decimals they were written as (0.04, not 0.03999999910593033).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
#[allow(non_snake_case)]
pub struct Constants {
    pub FRAME_STACK: usize,
    pub MAX_EPISODE_STEPS: u32,
    pub CONTROL_DT: f64,
    pub MAX_JOINT_STEP: f64,
    pub PHYSICS_SUBSTEPS: usize,
    pub PICK_DIST: f64,
    pub INSTALL_DIST: f64,
    pub HOME_Q: [f64; 6],
    pub tasks: std::collections::BTreeMap<&'static str, TaskDims>,
}

/// Observation and action sizes of one task.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct TaskDims {
    pub obs_frame_dim: usize,
    pub obs_dim: usize,
    pub act_dim: usize,
}

/// The decimal value an f32 constant was written as.
fn f32_exact(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(x as f64)
}

impl Constants {
    /// The constants of this build.
    pub fn get() -> Constants {
        Constants {
            FRAME_STACK,
            MAX_EPISODE_STEPS,
            CONTROL_DT: f32_exact(CONTROL_DT),
            MAX_JOINT_STEP,
            PHYSICS_SUBSTEPS,
            PICK_DIST: f32_exact(PICK_DIST),
            INSTALL_DIST: f32_exact(INSTALL_DIST),
            HOME_Q,
            tasks: Task::ALL
                .iter()
                .map(|t| {
                    let d = TaskDims {
                        obs_frame_dim: t.obs_frame_dim(),
                        obs_dim: t.obs_dim(),
                        act_dim: t.act_dim(),
                    };
                    (t.name(), d)
                })
                .collect(),
        }
    }
}
