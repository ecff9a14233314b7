//! One simulated episode stream: a Rapier world, the UR3, an end effector, a task object. The
//! arm's motion, the physics step (and its idle skip) and the frame stacking live here, the same
//! for every task; what the end effector does, how an episode is judged and what a frame holds
//! are the task's ([`crate::task`]). The test and tool API (snapshots, teleports) is in `tools.rs`.

mod tools;

use crate::spec::TaskSpec;
use crate::starts::{Start, Variation};
use crate::task::{State, TaskLogic};
use crate::world::{self, Scene};
use crate::{FRAME_STACK, SimError, Task};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier3d::prelude::*;
use std::sync::Arc;

/// Joint angles (rad) at the start of every episode: flange pointing straight down with the cup
/// centre / gripper TCP about 0.2 m above the table, in front of the base (y ≈ 0.25 m). The
/// built-in specs' `robot.home_q`; an env reads its spec's.
pub const HOME_Q: [f64; 6] = [
    -2.224540093430817,
    -1.829711527172729,
    2.0931403692644666,
    -1.8342251688866464,
    -1.5707963267948863,
    -0.6537437666359285,
];

/// A pose as plain numbers: translation (m) and quaternion `[x, y, z, w]`, Base frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct PoseRec {
    pub t: [f64; 3],
    pub q: [f64; 4],
}

impl PoseRec {
    pub(crate) fn from_pose(p: &Pose) -> Self {
        let r = p.rotation;
        PoseRec {
            t: [p.translation.x as f64, p.translation.y as f64, p.translation.z as f64],
            q: [r.x as f64, r.y as f64, r.z as f64, r.w as f64],
        }
    }
}

/// What happened in one env step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepOutcome {
    /// Sparse reward of this step (see [`Task`]).
    pub reward: f32,
    /// The episode ended by success (install/place/tightened) or failure (fall).
    pub terminated: bool,
    /// The episode hit its spec's `episode.max_steps` ([`MAX_EPISODE_STEPS`](crate::MAX_EPISODE_STEPS)
    /// for the built-in tasks) without terminating.
    pub truncated: bool,
    /// The object has been picked/gripped at some step of this episode (ever, including now):
    /// the paper's "picked rate" counts episodes with `picked` at their end. TileRow: any tile.
    pub picked: bool,
    /// The object is held by the end effector right now (after this step).
    pub held: bool,
    /// The success event (install / place / tightened; TileRow: the row complete, its last
    /// tile installed) happened in this step.
    pub installed: bool,
    /// The failure event (tile/block fell, nut spun off; a row laid in order: a tile picked out
    /// of its turn) happened in this step.
    pub fell: bool,
}

/// Full state for demo recording. Poses in the Base frame.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Snapshot {
    pub task: Task,
    /// Joint angles, rad.
    pub q: [f64; 6],
    /// tool0 (flange) pose.
    pub tool0: PoseRec,
    /// End-effector TCP: cup centre (suction) or point between the fingers (gripper).
    pub tcp: PoseRec,
    /// Object (tile / block / nut; TileRow: the current tile, see `row`) centre pose.
    pub object: PoseRec,
    /// Target pose of the object centre (tile/block on the pad, nut fully tightened).
    pub target: PoseRec,
    /// Suction state (TileSuction, TileRow; false otherwise).
    pub suction_on: bool,
    /// The object is held.
    pub held: bool,
    /// Finger gap, m (BlockGrip/Screw; 0 for TileSuction).
    pub gripper_width: f64,
    /// Spin command in effect: +1 tighten, 0 stopped, −1 loosen (Screw).
    pub spin: i8,
    /// Nut rotation about the bolt, rad (= turns · 2π; Screw).
    pub spin_angle: f64,
    /// Step index within the episode (0 right after reset).
    pub step: u32,
    /// The seed this episode was reset with.
    pub episode_seed: u64,
    /// Picked ever this episode (TileRow: any tile).
    pub picked: bool,
    /// The episode has terminated or been truncated.
    pub done: bool,
    /// TileRow: every tile of the row in row order (its pose, its target, picked and installed
    /// this episode); `object` and `target` above are the current tile's (the held one, else the
    /// first not installed). Empty, and not serialized, for the other tasks.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub row: Vec<crate::task::tile_row::RowTile>,
}

fn to_pose(iso: &ur3_kin::Pose) -> Pose {
    let t = iso.translation.vector;
    let c = iso.rotation.coords; // [i, j, k, w]
    Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32).normalize(),
    )
}

/// One environment: a Rapier world and its episode state.
pub struct Env {
    task: Task,
    logic: &'static dyn TaskLogic,
    s: State,
    rng: ChaCha8Rng,
    episode_seed: u64,
    step_idx: u32,
    done: bool,
    hist: Vec<f32>,
    skipped_steps: u64,
    skip_idle_physics: bool,
    variation: Variation,
    /// How the last finished episode ended ([`Env::last_placement`]).
    last_placement: Option<Placement>,
}

/// Where the object ended an episode, beside the success flag: what a tiler would check.
/// Base frame, m; yaw in degrees, modulo the object's symmetry (90° for a square tile).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Placement {
    /// Still held by the end effector at the end.
    pub held: bool,
    /// The object's centre above the target's (m; negative: below it, pushed into the pad).
    pub height_above_rest: f32,
    /// The object's centre to the target's in x and y (m).
    pub xy_error: f32,
    /// The target's yaw minus the object's (degrees, wrapped by the object's symmetry).
    pub yaw_error_deg: f32,
    /// The lip-to-face gap (m) when each hold of the episode began (suction heads; empty for
    /// the grippers): the TCP above the face the cups took (negative: pressed into it).
    pub hold_gaps: Vec<f32>,
}

/// Where episode `seed` of `task` puts the object's centre (tile, block or nut) at reset under
/// the paper's variation (the spec's `starts.paper`): x uniform in its range from the seed, y
/// fixed, resting height.
pub fn object_start(task: Task, seed: u64) -> Vector {
    let spec = TaskSpec::builtin(task);
    spec.starts.paper.variation().start(task, seed).object_centre(&spec)
}

/// The static scene of episode `seed` of `task` (what [`Env::scene`] gives after `reset(seed)`),
/// without building a world.
pub fn episode_scene(task: Task, seed: u64) -> Scene {
    world::scene(task, &TaskSpec::builtin(task).starts.paper.variation().start(task, seed))
}

impl Env {
    /// A new env; its episode seeds are drawn from a ChaCha8 RNG seeded with `seed`. The env is
    /// already reset (with the first drawn seed); call [`Env::reset`] to get the observation.
    pub fn new(task: Task, seed: u64) -> Env {
        Env::from_spec(TaskSpec::builtin(task), seed)
    }

    /// A new env of the task `spec` describes (its logic follows from the effector,
    /// [`TaskSpec::task`]), its episodes starting at the spec's paper starts; otherwise as
    /// [`Env::new`].
    pub fn from_spec(spec: Arc<TaskSpec>, seed: u64) -> Env {
        let task = spec.task();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let first = rng.next_u64();
        let (world, h) = world::build_spec(&spec, &Start::default());
        let variation = spec.starts.paper.variation();
        let mut env = Env {
            task,
            logic: task.logic(),
            s: State {
                arm: spec.arm(),
                spec,
                world,
                h,
                q: [0.0; 6],
                tool0: Pose::IDENTITY,
                suction_on: false,
                held: false,
                hold_offset: Pose::IDENTITY,
                width: 0.0,
                spin: 0,
                turns: 0.0,
                picked: false,
                start: Start::default(),
                target: Pose::IDENTITY,
                row: Default::default(),
                seal: Default::default(),
                hold_gaps: Vec::new(),
            },
            last_placement: None,
            rng,
            episode_seed: first,
            step_idx: 0,
            done: false,
            hist: vec![0.0; task.obs_dim()],
            skipped_steps: 0,
            skip_idle_physics: true,
            variation,
        };
        env.reset_with(first);
        env
    }

    /// The task of this env.
    pub fn task(&self) -> Task {
        self.task
    }

    /// The arm this env simulates (its spec's `robot.model`).
    pub fn arm(&self) -> &'static ur3_kin::UrModel {
        self.s.arm
    }

    /// The spec this env runs.
    pub fn spec(&self) -> &Arc<TaskSpec> {
        &self.s.spec
    }

    /// Joint motion (rad) per step at `|a| = 1`: the spec's `robot.joint_step`, else
    /// [`MAX_JOINT_STEP`](crate::MAX_JOINT_STEP) ([`TaskSpec::joint_step`]).
    pub fn joint_step(&self) -> f64 {
        self.s.spec.joint_step()
    }

    /// The action (six numbers) that moves the arm from where it is towards joint angles
    /// `q_goal` in one step, in the spec's action space ([`crate::action::action_toward`]).
    pub fn action_toward(&self, q_goal: &[f64; 6]) -> [f64; 6] {
        crate::action::action_toward(&self.s.spec, &self.s.q, q_goal)
    }

    /// Steps after which an episode is truncated (the spec's `episode.max_steps`).
    pub fn max_episode_steps(&self) -> u32 {
        self.s.spec.episode.max_steps
    }

    /// Start a new episode. `Some(s)`: the episode is a pure function of `s` (same seed + same
    /// actions → bit-identical trajectory). `None`: the next seed is drawn from the env's RNG.
    /// Writes the first observation (`obs_dim` floats) into `obs_out`.
    pub fn reset(&mut self, seed: Option<u64>, obs_out: &mut [f32]) -> Result<(), SimError> {
        check_len("obs", self.task.obs_dim(), obs_out.len())?;
        let s = seed.unwrap_or_else(|| self.rng.next_u64());
        self.reset_with(s);
        obs_out.copy_from_slice(&self.hist);
        Ok(())
    }

    /// The seed of the running episode.
    pub fn episode_seed(&self) -> u64 {
        self.episode_seed
    }

    /// Start episode `seed` at `start` (`None`: the paper's start of `seed`, where demos are
    /// recorded) and step it through `actions` (`k × act_dim`, row-major): the state a
    /// recorded episode had after its first `k` steps (same start + same actions →
    /// bit-identical trajectory), for training from demonstration states. Every action and the
    /// start are validated first, and an episode that would end within the replay is refused
    /// ([`SimError::InvalidArgument`]); on error the env is left reset to the start or, for a
    /// bad action or start, unchanged. Writes the observation after the last replayed step
    /// into `obs_out`; returns `k`.
    pub fn reset_replay(
        &mut self,
        seed: u64,
        start: Option<Start>,
        actions: &[f32],
        obs_out: &mut [f32],
    ) -> Result<usize, SimError> {
        check_len("obs", self.task.obs_dim(), obs_out.len())?;
        let ad = self.task.act_dim();
        if actions.len() % ad != 0 {
            return Err(SimError::InvalidArgument(format!(
                "replay actions have length {}, not a multiple of act_dim {ad}",
                actions.len()
            )));
        }
        for row in actions.chunks(ad) {
            check_action(self.task, row)?;
        }
        let start = match start {
            Some(st) => {
                st.check_in(&self.s.spec)?;
                st
            }
            None => self.s.spec.starts.paper.variation().start(self.task, seed),
        };
        self.reset_at(start, seed);
        for (k, row) in actions.chunks(ad).enumerate() {
            let out = self.step_unchecked(row);
            if out.terminated || out.truncated {
                self.reset_at(start, seed);
                return Err(SimError::InvalidArgument(format!(
                    "the replayed episode ends at step {} of {}",
                    k + 1,
                    actions.len() / ad
                )));
            }
        }
        obs_out.copy_from_slice(&self.hist);
        Ok(actions.len() / ad)
    }

    /// How this env's episodes start from now on (the next reset); refused if out of range.
    pub fn set_variation(&mut self, v: Variation) -> Result<(), SimError> {
        v.validate_for(self.s.arm)?;
        self.variation = v;
        Ok(())
    }

    /// How this env's episodes start.
    pub fn variation(&self) -> Variation {
        self.variation
    }

    /// Start an episode at `start` ([`Start::check`]ed first; on error nothing changes), recorded
    /// as episode `seed`. Writes the first observation into `obs_out`.
    pub fn reset_start(&mut self, start: Start, seed: u64, obs_out: &mut [f32]) -> Result<(), SimError> {
        check_len("obs", self.task.obs_dim(), obs_out.len())?;
        start.check_in(&self.s.spec)?;
        self.reset_at(start, seed);
        obs_out.copy_from_slice(&self.hist);
        Ok(())
    }

    /// [`Env::reset_start`] without the check, for a start this simulator drew itself (a restore).
    pub(crate) fn reset_start_unchecked(&mut self, start: Start, seed: u64, obs_out: &mut [f32]) {
        self.reset_at(start, seed);
        obs_out.copy_from_slice(&self.hist);
    }

    /// Where the running episode started.
    pub fn start(&self) -> Start {
        self.s.start
    }

    fn reset_with(&mut self, seed: u64) {
        self.reset_at(self.variation.start(self.task, seed), seed);
    }

    fn reset_at(&mut self, start: Start, seed: u64) {
        let (w, h) = world::build_spec(&self.s.spec, &start);
        self.s.world = w;
        self.s.h = h;
        self.episode_seed = seed;
        self.s.start = start;
        self.s.target =
            Pose::from_parts(start.target(&self.s.spec), Rotation::from_rotation_z(start.pad_yaw));
        self.step_idx = 0;
        self.done = false;
        self.s.held = false;
        self.s.hold_offset = Pose::IDENTITY;
        self.s.picked = false;
        self.s.hold_gaps.clear();
        self.logic.reset(&mut self.s);
        self.teleport_arm(self.s.spec.robot.home_q);
        self.hist.iter_mut().for_each(|v| *v = 0.0);
        self.push_frame();
    }

    fn teleport_arm(&mut self, q: [f64; 6]) {
        self.s.q = q;
        let frames = ur3_kin::fk_all(self.s.arm, &q);
        for i in 0..6 {
            let p = to_pose(&frames[i + 1]);
            if let Some(b) = self.s.world.bodies.get_mut(self.s.h.links[i]) {
                b.set_position(p, true);
                b.set_next_kinematic_position(p);
            }
        }
        self.s.tool0 = to_pose(&frames[6]);
        self.logic.place_attached(&mut self.s, true);
    }

    /// Shift the frame stack by one and write the task's newest frame last.
    fn push_frame(&mut self) {
        let fd = self.logic.obs_frame_dim();
        self.hist.copy_within(fd.., 0);
        self.logic.write_frame(&self.s, &mut self.hist[(FRAME_STACK - 1) * fd..]);
    }

    /// The current stacked observation (`obs_dim` floats, oldest frame first).
    pub fn observation(&self) -> &[f32] {
        &self.hist
    }

    /// Advance one env step ([`CONTROL_DT`](crate::CONTROL_DT) s). See the crate docs for the action layout.
    /// On error nothing changes.
    pub fn step(&mut self, action: &[f32], obs_out: &mut [f32]) -> Result<StepOutcome, SimError> {
        check_len("obs", self.task.obs_dim(), obs_out.len())?;
        check_action(self.task, action)?;
        if self.done {
            return Err(SimError::EpisodeOver);
        }
        let out = self.step_unchecked(action);
        obs_out.copy_from_slice(&self.hist);
        Ok(out)
    }

    /// Whether the TCP is outside the spec's `robot.tcp_box` (false without one).
    fn tcp_left_its_box(&self) -> bool {
        let Some([lo, hi]) = self.s.spec.robot.tcp_box else { return false };
        let t = self.s.tcp().translation;
        [t.x, t.y, t.z].iter().enumerate().any(|(i, &v)| f64::from(v) < lo[i] || f64::from(v) > hi[i])
    }

    /// Step with an already validated action (length and finiteness checked by the caller).
    pub(crate) fn step_unchecked(&mut self, action: &[f32]) -> StepOutcome {
        let qn = crate::action::joint_motion(&self.s.spec, &self.s.q, action);
        let frames = ur3_kin::fk_all(self.s.arm, &qn);
        for i in 0..6 {
            let p = to_pose(&frames[i + 1]);
            if let Some(b) = self.s.world.bodies.get_mut(self.s.h.links[i]) {
                b.set_next_kinematic_position(p);
            }
        }
        self.s.q = qn;
        self.s.tool0 = to_pose(&frames[6]);
        let mut out = StepOutcome::default();
        self.logic.effector(&mut self.s, action, &mut out);
        if self.s.held && self.logic.carries_object() {
            let p = self.s.tool0 * self.s.hold_offset;
            if let Some(b) = self.s.world.bodies.get_mut(self.s.h.object) {
                b.set_next_kinematic_position(p);
            }
        }
        let idle = self.physics_idle();
        if self.skip_idle_physics && idle {
            // Nothing dynamic can move this step: place the kinematic bodies where the step
            // would have put them and skip the solver (exact: a sleeping, untouched body does not
            // move in Rapier either).
            self.skipped_steps += 1;
            for (_, b) in self.s.world.bodies.iter_mut() {
                if b.is_kinematic() {
                    let p = *b.next_position();
                    b.set_position(p, false);
                    b.set_next_kinematic_position(p);
                }
            }
        } else {
            self.s.world.step();
        }
        self.step_idx += 1;
        self.logic.evaluate(&mut self.s, &mut out);
        if !out.terminated && self.tcp_left_its_box() {
            out.reward += self.s.spec.rewards.fail; // a protective stop at a safety plane
            out.fell = true;
            out.terminated = true;
        }
        out.picked = self.s.picked;
        out.held = self.s.held;
        if !out.terminated && self.step_idx >= self.s.spec.episode.max_steps {
            out.truncated = true;
        }
        self.done = out.terminated || out.truncated;
        if self.done {
            self.last_placement = self.placement();
        }
        self.push_frame();
        out
    }

    /// Where the object is now, as [`Placement`] judges it (`None` for the Screw task, whose
    /// nut rides its bolt).
    pub fn placement(&self) -> Option<Placement> {
        if self.task == Task::Screw {
            return None;
        }
        let p = self.s.object_pose();
        let d = p.translation - self.s.target.translation;
        let half = self.s.spec.object.half_extents.unwrap_or([0.0; 3]);
        let (yo, period) = crate::task::tile_place::yaw_and_period(&p, half);
        let (yt, _) = crate::task::tile_place::yaw_and_period(&self.s.target, half);
        Some(Placement {
            held: self.s.held,
            height_above_rest: d.z,
            xy_error: (d.x * d.x + d.y * d.y).sqrt(),
            yaw_error_deg: crate::task::tile_place::wrap(yt - yo, period).to_degrees(),
            hold_gaps: self.s.hold_gaps.clone(),
        })
    }

    /// The [`Placement`] at the end of this env's last finished episode (terminated or
    /// truncated; kept through the reset that follows), `None` before one has finished.
    pub fn last_placement(&self) -> Option<&Placement> {
        self.last_placement.as_ref()
    }

    /// Whether any arm/finger collider (or, in a row, the held object's), swept from its current
    /// to its next pose, comes within [`SKIP_MARGIN`] of the bounding box of the object `object`.
    fn arm_near_object(&self, object: RigidBodyHandle) -> bool {
        let bodies = &self.s.world.bodies;
        let colliders = &self.s.world.colliders;
        let Some(obj) = bodies.get(object) else { return true };
        let aabb_of = |pose: &Pose, c: ColliderHandle| {
            colliders.get(c).map(|col| {
                let local = col.position_wrt_parent().copied().unwrap_or(Pose::IDENTITY);
                col.shape().compute_aabb(&(*pose * local))
            })
        };
        let mut obj_box: Option<Aabb> = None;
        for &c in obj.colliders() {
            if let Some(a) = aabb_of(obj.position(), c) {
                obj_box = Some(obj_box.map_or(a, |o| o.merged(&a)));
            }
        }
        let Some(obj_box) = obj_box.map(|a| a.loosened(SKIP_MARGIN)) else { return true };
        let fingers = self.s.h.fingers.as_ref().map(|f| f.as_slice()).unwrap_or(&[]);
        // A held tile of a row moves with the arm and pushes the others.
        let carried = self.s.held && !self.s.h.row.is_empty() && self.s.h.object != object;
        let held = if carried { std::slice::from_ref(&self.s.h.object) } else { &[] };
        for h in self.s.h.links.iter().chain(fingers).chain(held) {
            let Some(b) = bodies.get(*h) else { continue };
            for &c in b.colliders() {
                let (Some(a0), Some(a1)) = (aabb_of(b.position(), c), aabb_of(b.next_position(), c)) else {
                    continue;
                };
                if a0.merged(&a1).intersects(&obj_box) {
                    return true;
                }
            }
        }
        false
    }

    /// Decide this step's physics: wake a sleeping object the arm is about to reach (in every
    /// mode, so contacts always act on an awake body), and return true when the step could not
    /// move anything: every dynamic body (the object, or each object of a row) is kinematic
    /// (held, or the nut) or asleep with the arm away from it.
    fn physics_idle(&mut self) -> bool {
        if self.s.h.row.is_empty() {
            return self.object_idle(self.s.h.object);
        }
        let mut idle = true;
        for i in 0..self.s.h.row.len() {
            // Every object is judged (not only up to the first busy one): each sleeping object
            // the arm reaches is woken.
            idle &= self.object_idle(self.s.h.row[i]);
        }
        idle
    }

    /// [`Env::physics_idle`] for one object: wake it if it sleeps and the arm is about to reach
    /// it; true when the step cannot move it.
    fn object_idle(&mut self, object: RigidBodyHandle) -> bool {
        let Some(obj) = self.s.world.bodies.get(object) else { return false };
        if !obj.is_dynamic() {
            return true;
        }
        if !obj.is_sleeping() {
            return false;
        }
        if self.arm_near_object(object) {
            self.s.world.wake_up(object, true);
            return false;
        }
        true
    }

    /// Diagnostics: turn the idle-physics skip on (default) or off (every step runs the solver).
    pub fn set_skip_idle_physics(&mut self, on: bool) {
        self.skip_idle_physics = on;
    }

    /// Env steps whose physics was skipped by the idle test (diagnostics, benchmarks).
    pub fn skipped_steps(&self) -> u64 {
        self.skipped_steps
    }
}

/// Distance (m) within which an arm collider's swept box must come to the resting object's box
/// for the physics step to run (5 × the contact prediction distance).
pub const SKIP_MARGIN: f32 = 0.02;
fn check_len(what: &'static str, expected: usize, got: usize) -> Result<(), SimError> {
    if expected != got {
        return Err(SimError::BufferShape { what, expected, got });
    }
    Ok(())
}

/// Validate an action's length and finiteness.
pub(crate) fn check_action(task: Task, action: &[f32]) -> Result<(), SimError> {
    if action.len() != task.act_dim() {
        return Err(SimError::ActionShape { expected: task.act_dim(), got: action.len(), task: task.name() });
    }
    if let Some((index, &value)) = action.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(SimError::NonFiniteAction { index, value });
    }
    Ok(())
}
