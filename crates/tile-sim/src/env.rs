//! One simulated episode stream: a Rapier world, the UR3, an end effector, a task object.

use crate::starts::{Start, Variation};
use crate::world::{self, Handles, Scene};
use crate::{CONTROL_DT, FRAME_STACK, MAX_EPISODE_STEPS, MAX_JOINT_STEP, SCREW_TURNS, SimError, Task};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier3d::prelude::*;
use std::f64::consts::PI;

/// Joint angles (rad) at the start of every episode: flange pointing straight down with the cup
/// centre / gripper TCP about 0.2 m above the table, in front of the base (y ≈ 0.25 m).
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
    fn from_pose(p: &Pose) -> Self {
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
    /// The episode hit [`MAX_EPISODE_STEPS`] without terminating.
    pub truncated: bool,
    /// The object has been picked/gripped at some step of this episode (ever, including now):
    /// the paper's "picked rate" counts episodes with `picked` at their end.
    pub picked: bool,
    /// The object is held by the end effector right now (after this step).
    pub held: bool,
    /// The success event (install / place / tightened) happened in this step.
    pub installed: bool,
    /// The failure event (tile/block fell, nut spun off) happened in this step.
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
    /// Object (tile / block / nut) centre pose.
    pub object: PoseRec,
    /// Target pose of the object centre (tile/block on the pad, nut fully tightened).
    pub target: PoseRec,
    /// Suction state (TileSuction; false otherwise).
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
    /// Picked ever this episode.
    pub picked: bool,
    /// The episode has terminated or been truncated.
    pub done: bool,
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
    world: PhysicsWorld,
    h: Handles,
    rng: ChaCha8Rng,
    episode_seed: u64,
    q: [f64; 6],
    tool0: Pose,
    step_idx: u32,
    done: bool,
    suction_on: bool,
    held: bool,
    hold_offset: Pose,
    width: f32,
    spin: i8,
    turns: f64,
    picked: bool,
    start: Start,
    target: Pose,
    hist: Vec<f32>,
    skipped_steps: u64,
    skip_idle_physics: bool,
    variation: Variation,
}

/// Where episode `seed` of `task` puts the object's centre (tile, block or nut) at reset under
/// the paper's variation: x uniform in `[OBJECT_X_MIN, OBJECT_X_MAX]` from the seed, y =
/// `OBJECT_Y`, resting height.
pub fn object_start(task: Task, seed: u64) -> Vector {
    Variation::default().start(task, seed).object_centre(task)
}

/// The static scene of episode `seed` of `task` (what [`Env::scene`] gives after `reset(seed)`),
/// without building a world.
pub fn episode_scene(task: Task, seed: u64) -> Scene {
    world::scene(task, &Variation::default().start(task, seed))
}

impl Env {
    /// A new env; its episode seeds are drawn from a ChaCha8 RNG seeded with `seed`. The env is
    /// already reset (with the first drawn seed); call [`Env::reset`] to get the observation.
    pub fn new(task: Task, seed: u64) -> Env {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let first = rng.next_u64();
        let (world, h) = world::build(task, &Start::default());
        let mut env = Env {
            task,
            world,
            h,
            rng,
            episode_seed: first,
            q: HOME_Q,
            tool0: Pose::IDENTITY,
            step_idx: 0,
            done: false,
            suction_on: false,
            held: false,
            hold_offset: Pose::IDENTITY,
            width: world::GRIP_MAX_WIDTH,
            spin: 0,
            turns: 0.0,
            picked: false,
            start: Start::default(),
            target: Pose::IDENTITY,
            hist: vec![0.0; task.obs_dim()],
            skipped_steps: 0,
            skip_idle_physics: true,
            variation: Variation::default(),
        };
        env.reset_with(first);
        env
    }

    /// The task of this env.
    pub fn task(&self) -> Task {
        self.task
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
                st.check(self.task)?;
                st
            }
            None => Variation::default().start(self.task, seed),
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
        v.validate()?;
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
        start.check(self.task)?;
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
        self.start
    }

    fn reset_with(&mut self, seed: u64) {
        self.reset_at(self.variation.start(self.task, seed), seed);
    }

    fn reset_at(&mut self, start: Start, seed: u64) {
        let (w, h) = world::build(self.task, &start);
        self.world = w;
        self.h = h;
        self.episode_seed = seed;
        self.start = start;
        self.target = Pose::from_translation(start.target(self.task));
        self.step_idx = 0;
        self.done = false;
        self.suction_on = false;
        self.held = false;
        self.hold_offset = Pose::IDENTITY;
        self.width = world::GRIP_MAX_WIDTH;
        self.spin = 0;
        self.turns = 0.0;
        self.picked = false;
        self.teleport_arm(HOME_Q);
        self.hist.iter_mut().for_each(|v| *v = 0.0);
        self.push_frame();
    }

    fn teleport_arm(&mut self, q: [f64; 6]) {
        self.q = q;
        let frames = ur3_kin::fk_all(&ur3_kin::UR3, &q);
        for i in 0..6 {
            let p = to_pose(&frames[i + 1]);
            if let Some(b) = self.world.bodies.get_mut(self.h.links[i]) {
                b.set_position(p, true);
                b.set_next_kinematic_position(p);
            }
        }
        self.tool0 = to_pose(&frames[6]);
        self.place_fingers(true);
        if self.task == Task::Screw {
            self.place_nut(true);
        }
    }

    fn place_fingers(&mut self, teleport: bool) {
        if let Some(f) = self.h.fingers {
            for (k, s) in [(0usize, 1.0f32), (1, -1.0)] {
                let p = self.tool0
                    * Pose::from_translation(Vector::new(
                        0.0,
                        s * (self.width / 2.0 + world::FINGER_HALF[1]),
                        world::FINGER_Z,
                    ));
                if let Some(b) = self.world.bodies.get_mut(f[k]) {
                    if teleport {
                        b.set_position(p, true);
                    }
                    b.set_next_kinematic_position(p);
                }
            }
        }
    }

    fn place_nut(&mut self, teleport: bool) {
        let z = world::NUT_START_Z - (self.turns as f32) * world::THREAD_PITCH;
        let ang = (self.turns * 2.0 * PI) as f32;
        // Tightening a right-hand thread turns the nut clockwise seen from above (−Z rotation).
        let p = Pose::from_parts(
            Vector::new(self.start.object_xy[0], self.start.object_xy[1], z),
            Rotation::from_rotation_z(-ang),
        );
        if let Some(b) = self.world.bodies.get_mut(self.h.object) {
            if teleport {
                b.set_position(p, true);
            }
            b.set_next_kinematic_position(p);
        }
    }

    fn tcp_z(&self) -> f32 {
        match self.task {
            Task::TileSuction => world::CUP_TCP_Z,
            _ => world::GRIP_TCP_Z,
        }
    }

    fn tcp(&self) -> Pose {
        self.tool0 * Pose::from_translation(Vector::new(0.0, 0.0, self.tcp_z()))
    }

    fn object_pose(&self) -> Pose {
        self.world.bodies.get(self.h.object).map(|b| *b.position()).unwrap_or(Pose::IDENTITY)
    }

    fn push_frame(&mut self) {
        let fd = self.task.obs_frame_dim();
        self.hist.copy_within(fd.., 0);
        let tcp = self.tcp().translation;
        let obj = self.object_pose().translation;
        let tgt = self.target.translation;
        let q = self.q;
        let f = &mut self.hist[(FRAME_STACK - 1) * fd..];
        for i in 0..6 {
            f[i] = q[i] as f32;
        }
        let mut k = 6;
        match self.task {
            Task::TileSuction => {
                f[k] = if self.suction_on { 1.0 } else { -1.0 };
                k += 1;
            }
            Task::BlockGrip => {
                f[k] = self.width;
                k += 1;
            }
            Task::Screw => {
                f[k] = self.width;
                f[k + 1] = self.spin as f32;
                k += 2;
            }
        }
        for v in [tcp, tgt, obj] {
            f[k] = v.x;
            f[k + 1] = v.y;
            f[k + 2] = v.z;
            k += 3;
        }
        if self.task == Task::Screw {
            f[k] = self.turns as f32;
        }
    }

    /// The current stacked observation (`obs_dim` floats, oldest frame first).
    pub fn observation(&self) -> &[f32] {
        &self.hist
    }

    /// Advance one env step ([`CONTROL_DT`] s). See the crate docs for the action layout.
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

    /// Step with an already validated action (length and finiteness checked by the caller).
    pub(crate) fn step_unchecked(&mut self, action: &[f32]) -> StepOutcome {
        let mut qn = self.q;
        for i in 0..6 {
            let a = action[i].clamp(-1.0, 1.0) as f64;
            qn[i] = (self.q[i] + a * MAX_JOINT_STEP).clamp(-PI, PI);
        }
        let frames = ur3_kin::fk_all(&ur3_kin::UR3, &qn);
        for i in 0..6 {
            let p = to_pose(&frames[i + 1]);
            if let Some(b) = self.world.bodies.get_mut(self.h.links[i]) {
                b.set_next_kinematic_position(p);
            }
        }
        self.q = qn;
        self.tool0 = to_pose(&frames[6]);
        let cmd = action[6];
        let mut out = StepOutcome::default();
        match self.task {
            Task::TileSuction => self.suction_logic(cmd, &mut out),
            Task::BlockGrip | Task::Screw => self.gripper_logic(cmd, &mut out),
        }
        if self.task == Task::Screw {
            let s = action[7];
            self.spin = if s >= 0.5 {
                1
            } else if s <= -0.5 {
                -1
            } else {
                0
            };
            self.screw_logic();
            self.place_nut(false);
        }
        if self.held && self.task != Task::Screw {
            let p = self.tool0 * self.hold_offset;
            if let Some(b) = self.world.bodies.get_mut(self.h.object) {
                b.set_next_kinematic_position(p);
            }
        }
        let idle = self.physics_idle();
        if self.skip_idle_physics && idle {
            // Nothing dynamic can move this step: place the kinematic bodies where the step
            // would have put them and skip the solver (exact: a sleeping, untouched body does not
            // move in Rapier either).
            self.skipped_steps += 1;
            for (_, b) in self.world.bodies.iter_mut() {
                if b.is_kinematic() {
                    let p = *b.next_position();
                    b.set_position(p, false);
                    b.set_next_kinematic_position(p);
                }
            }
        } else {
            self.world.step();
        }
        self.step_idx += 1;
        self.evaluate(&mut out);
        out.picked = self.picked;
        out.held = self.held;
        if !out.terminated && self.step_idx >= MAX_EPISODE_STEPS {
            out.truncated = true;
        }
        self.done = out.terminated || out.truncated;
        self.push_frame();
        out
    }

    /// Whether any arm/finger collider, swept from its current to its next pose, comes within
    /// [`SKIP_MARGIN`] of the object's bounding box.
    fn arm_near_object(&self) -> bool {
        let bodies = &self.world.bodies;
        let colliders = &self.world.colliders;
        let Some(obj) = bodies.get(self.h.object) else { return true };
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
        let fingers = self.h.fingers.as_ref().map(|f| f.as_slice()).unwrap_or(&[]);
        for h in self.h.links.iter().chain(fingers) {
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
    /// move anything: the only dynamic body (the object) is kinematic (held, or the nut) or asleep
    /// with the arm away from it.
    fn physics_idle(&mut self) -> bool {
        let Some(obj) = self.world.bodies.get(self.h.object) else { return false };
        if !obj.is_dynamic() {
            return true;
        }
        if !obj.is_sleeping() {
            return false;
        }
        if self.arm_near_object() {
            self.world.wake_up(self.h.object, true);
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

    /// Let go of the held object: it becomes dynamic at its current pose, moving with the
    /// velocity the grasp point has during this step's arm motion (angular velocity zero).
    fn release_object(&mut self) {
        let target = (self.tool0 * self.hold_offset).translation;
        self.set_object_kinematic(false);
        if let Some(b) = self.world.bodies.get_mut(self.h.object) {
            let v = (target - b.position().translation) / CONTROL_DT;
            b.set_linvel(v, true);
            b.set_angvel(Vector::ZERO, true);
        }
    }

    fn set_object_kinematic(&mut self, kinematic: bool) {
        if let Some(b) = self.world.bodies.get_mut(self.h.object) {
            let ty = if kinematic { RigidBodyType::KinematicPositionBased } else { RigidBodyType::Dynamic };
            b.set_body_type(ty, true);
        }
    }

    fn suction_logic(&mut self, cmd: f32, out: &mut StepOutcome) {
        if cmd >= 0.5 {
            self.suction_on = true;
        } else if cmd <= -0.5 {
            self.suction_on = false;
        }
        if self.held && !self.suction_on {
            self.held = false;
            self.release_object();
        }
        if !self.held && self.suction_on {
            let tile = self.object_pose();
            let up = tile.rotation * Vector::Z;
            let s = if up.z >= 0.0 { 1.0 } else { -1.0 };
            let grasp = tile.translation + up * (s * world::TILE_HALF[2]);
            if (self.tcp().translation - grasp).length() < PICK_DIST {
                self.held = true;
                self.hold_offset = self.tool0.inverse() * tile;
                self.set_object_kinematic(true);
                if !self.picked {
                    self.picked = true;
                    out.reward += 1.0;
                }
            }
        }
    }

    fn gripper_logic(&mut self, cmd: f32, out: &mut StepOutcome) {
        let dw = world::GRIP_SPEED * CONTROL_DT;
        if cmd >= 0.5 {
            if !self.held {
                let new_w = (self.width - dw).max(0.0);
                if let Some(contact_w) = self.between_fingers() {
                    if new_w <= contact_w {
                        self.width = contact_w.min(self.width);
                        self.held = true;
                        if self.task == Task::BlockGrip {
                            // The closing fingers centre the block between them.
                            let tcp = self.tcp();
                            let mut local = tcp.inverse() * self.object_pose();
                            local.translation.y = 0.0;
                            let tool_to_tcp = self.tool0.inverse() * tcp;
                            self.hold_offset = tool_to_tcp * local;
                            self.set_object_kinematic(true);
                        }
                        if !self.picked {
                            self.picked = true;
                            out.reward += 1.0;
                        }
                    } else {
                        self.width = new_w;
                    }
                } else {
                    self.width = new_w;
                }
            }
        } else if cmd <= -0.5 {
            self.width = (self.width + dw).min(world::GRIP_MAX_WIDTH);
            if self.held {
                self.held = false;
                if self.task == Task::BlockGrip {
                    self.release_object();
                }
            }
        }
        self.place_fingers(false);
    }

    /// If the object lies between the fingers, the finger gap at which they touch it.
    fn between_fingers(&self) -> Option<f32> {
        let tcp = self.tcp();
        let obj = self.object_pose();
        let p = tcp.inverse_transform_point(obj.translation);
        let tool_y = tcp.rotation * Vector::Y;
        let tool_x = tcp.rotation * Vector::X;
        let tool_z = tcp.rotation * Vector::Z;
        match self.task {
            Task::BlockGrip => {
                let ext = |u: Vector| {
                    let r = obj.rotation;
                    world::BLOCK_HALF
                        * ((r * Vector::X).dot(u).abs()
                            + (r * Vector::Y).dot(u).abs()
                            + (r * Vector::Z).dot(u).abs())
                };
                let (ex, ey, ez) = (ext(tool_x), ext(tool_y), ext(tool_z));
                let inside = p.x.abs() < world::FINGER_HALF[0] + ex - 0.005
                    && p.z.abs() < world::FINGER_HALF[2] + ez - 0.005
                    && p.y.abs() < self.width / 2.0;
                inside.then_some(2.0 * ey)
            }
            Task::Screw => {
                let aligned = tool_z.dot(-Vector::Z) > ALIGN_COS;
                let inside = aligned
                    && p.x.abs() < 0.006
                    && p.y.abs() < 0.006
                    && p.z.abs() < world::FINGER_HALF[2] - world::NUT_HALF_HEIGHT
                    && world::NUT_RADIUS <= self.width / 2.0 + 1e-4;
                inside.then_some(2.0 * world::NUT_RADIUS)
            }
            Task::TileSuction => None,
        }
    }

    fn screw_logic(&mut self) {
        if !self.held {
            return;
        }
        let tcp = self.tcp();
        let nut = self.object_pose().translation;
        let d = tcp.translation - nut;
        let aligned = (tcp.rotation * Vector::Z).dot(-Vector::Z) > ALIGN_COS;
        if !aligned || d.length() > 0.01 {
            // The arm pulled away: the fingers slip off the nut.
            self.held = false;
            return;
        }
        if self.spin != 0 {
            self.turns += self.spin as f64 * (world::SPIN_RATE * CONTROL_DT) as f64;
        }
    }

    fn evaluate(&mut self, out: &mut StepOutcome) {
        match self.task {
            Task::TileSuction => {
                let (p, v) = self.object_state();
                if (p.translation - self.target.translation).length() < INSTALL_DIST {
                    out.reward += 1.0;
                    out.installed = true;
                    out.terminated = true;
                } else if fell(&p, v, self.held) {
                    out.reward -= 0.5;
                    out.fell = true;
                    out.terminated = true;
                }
            }
            Task::BlockGrip => {
                let (p, v) = self.object_state();
                if !self.held && (p.translation - self.target.translation).length() < PLACE_DIST {
                    out.reward += 1.0;
                    out.installed = true;
                    out.terminated = true;
                } else if !p.is_finite()
                    || p.translation.z < FALL_Z
                    || (!self.held && v.z < -FALL_SPEED * 2.0)
                {
                    out.reward -= 0.5;
                    out.fell = true;
                    out.terminated = true;
                }
            }
            Task::Screw => {
                if self.turns >= SCREW_TURNS - 1e-9 {
                    out.reward += 1.0;
                    out.installed = true;
                    out.terminated = true;
                } else if self.turns < -1.0 {
                    out.reward -= 0.5;
                    out.fell = true;
                    out.terminated = true;
                }
            }
        }
    }

    fn object_state(&self) -> (Pose, Vector) {
        self.world
            .bodies
            .get(self.h.object)
            .map(|b| (*b.position(), b.linvel()))
            .unwrap_or((Pose::IDENTITY, Vector::ZERO))
    }

    /// Everything needed to record or replay the current state.
    pub fn snapshot(&self) -> Snapshot {
        Snapshot {
            task: self.task,
            q: self.q,
            tool0: PoseRec::from_pose(&self.tool0),
            tcp: PoseRec::from_pose(&self.tcp()),
            object: PoseRec::from_pose(&self.object_pose()),
            target: PoseRec::from_pose(&self.target),
            suction_on: self.suction_on,
            held: self.held,
            gripper_width: if self.task == Task::TileSuction { 0.0 } else { self.width as f64 },
            spin: self.spin,
            spin_angle: self.turns * 2.0 * PI,
            step: self.step_idx,
            episode_seed: self.episode_seed,
            picked: self.picked,
            done: self.done,
        }
    }

    /// Poses of the arm's DH frames 0..=6 in the Base frame (`ur3_kin::fk_all` of the current
    /// joints; 0 = Base, 6 = tool0), for drawing the `SceneFrame::Link(i)` items.
    pub fn link_poses(&self) -> [PoseRec; 7] {
        let f = ur3_kin::fk_all(&ur3_kin::UR3, &self.q);
        std::array::from_fn(|i| PoseRec::from_pose(&to_pose(&f[i])))
    }

    /// Static geometry of this env's scene (the object item is relative to the object pose).
    pub fn scene(&self) -> Scene {
        world::scene(self.task, &self.start)
    }

    /// Test/tool API: teleport the arm to joint angles `q` (rad, each within [-π, π]).
    /// A held object moves with the flange. The observation is refreshed at the next step.
    pub fn set_joints(&mut self, q: [f64; 6]) -> Result<(), SimError> {
        if q.iter().any(|v| !v.is_finite() || v.abs() > PI) {
            return Err(SimError::InvalidState(format!(
                "joint angles must be finite and within [-pi, pi]: {q:?}"
            )));
        }
        self.teleport_arm(q);
        if self.held && self.task != Task::Screw {
            let p = self.tool0 * self.hold_offset;
            if let Some(b) = self.world.bodies.get_mut(self.h.object) {
                b.set_position(p, true);
                b.set_next_kinematic_position(p);
            }
        }
        Ok(())
    }

    /// Test/tool API: teleport the object (tile/block) to translation `t` (m) and rotation
    /// `q = [x, y, z, w]` with zero velocity; any hold is released (suction/grip state unchanged).
    /// For Screw, sets the nut's turn count instead (`t` ignored, rotation ignored): use
    /// [`Env::set_turns`].
    pub fn set_object_pose(&mut self, t: [f64; 3], q: [f64; 4]) -> Result<(), SimError> {
        if t.iter().chain(q.iter()).any(|v| !v.is_finite()) {
            return Err(SimError::InvalidState("object pose must be finite".into()));
        }
        if self.task == Task::Screw {
            return Err(SimError::InvalidState("the nut rides the bolt: use set_turns".into()));
        }
        let rot = Rotation::from_xyzw(q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32);
        if rot.length() < 1e-6 {
            return Err(SimError::InvalidState("zero quaternion".into()));
        }
        let p = Pose::from_parts(Vector::new(t[0] as f32, t[1] as f32, t[2] as f32), rot.normalize());
        if self.held {
            self.held = false;
            self.set_object_kinematic(false);
        }
        if let Some(b) = self.world.bodies.get_mut(self.h.object) {
            b.set_position(p, true);
            b.set_linvel(Vector::ZERO, true);
            b.set_angvel(Vector::ZERO, true);
        }
        Ok(())
    }

    /// Test/tool API (Screw): set the nut's turn count (0 = just caught the thread).
    pub fn set_turns(&mut self, turns: f64) -> Result<(), SimError> {
        if !turns.is_finite() || self.task != Task::Screw {
            return Err(SimError::InvalidState("set_turns needs the Screw task and a finite count".into()));
        }
        self.turns = turns;
        self.place_nut(true);
        Ok(())
    }

    /// True when every body pose in the world is finite and within 10 m of the base.
    pub fn bodies_sane(&self) -> bool {
        self.world.bodies.iter().all(|(_, b)| {
            let p = b.position();
            p.is_finite() && p.translation.length() < 10.0
        })
    }
}

/// Distance (m) within which an arm collider's swept box must come to the resting object's box
/// for the physics step to run (5 × the contact prediction distance).
pub const SKIP_MARGIN: f32 = 0.02;
/// Pick threshold: cup centre to grasp point (paper §5.1), m.
pub const PICK_DIST: f32 = 0.04;
/// Install threshold: tile centre to target (paper §5.1), m.
pub const INSTALL_DIST: f32 = 0.03;
/// BlockGrip place threshold, m.
pub const PLACE_DIST: f32 = 0.02;
/// Fall rules: centre below this height (m, the table top is 0), tilt above 45°, or falling
/// faster than `FALL_SPEED` (m/s) while not held.
pub const FALL_Z: f32 = -0.02;
pub const FALL_SPEED: f32 = 1.0;
const FALL_TILT_COS: f32 = std::f32::consts::FRAC_1_SQRT_2;
/// The screwing TCP must point down within ~20° of the bolt axis.
const ALIGN_COS: f32 = 0.94;

fn fell(p: &Pose, v: Vector, held: bool) -> bool {
    if !p.is_finite() || p.translation.z < FALL_Z {
        return true;
    }
    if held {
        return false;
    }
    (p.rotation * Vector::Z).z.abs() < FALL_TILT_COS || v.z < -FALL_SPEED
}

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
