//! One teleoperation episode: hand frames in, control steps out, a demo recorded.

use crate::clutch::{Clutch, ClutchInput, Mapping};
use crate::filter::OneEuro;
use crate::{BRANCH_JUMP, TeleopError, command_of, recorded_command, wrap_to_pi};
use demo_log::{DemoError, DemoWriter, HandFrame, Pose as RecPose, StepRecord};
use std::collections::BTreeMap;
use std::sync::Arc;
use tile_sim::{Constants, Env, Snapshot, Task, TaskSpec};
use ur3_kin::nalgebra::Matrix4;
use ur3_kin::{Calibration, HandLayout, HandPoints, Handedness, IkOptions, urdf};

/// Where a session's episode goes: [`DemoWriter`] writes an MCAP demo.
pub trait Recorder {
    /// One raw hand frame at episode time `t` (s since the episode's first frame).
    ///
    /// # Errors
    /// The writer's.
    fn hand_frame(&mut self, frame: &HandFrame, t: f64) -> Result<(), DemoError>;
    /// One control step, with the arm's link transforms at its joints ([`Links`]).
    ///
    /// # Errors
    /// The writer's.
    fn step(&mut self, rec: &StepRecord, links: &Links) -> Result<(), DemoError>;
}

/// The arm's parent-to-child URDF link transforms at one joint vector
/// (`ur3_kin::urdf::link_transforms`): `/tf` and the page's frames both come from it.
pub type Links = Vec<(&'static str, &'static str, ur3_kin::Pose)>;

impl Recorder for DemoWriter {
    fn hand_frame(&mut self, frame: &HandFrame, t: f64) -> Result<(), DemoError> {
        self.write_hand_frame(frame, t)
    }
    fn step(&mut self, rec: &StepRecord, links: &Links) -> Result<(), DemoError> {
        self.write_step_with_links(rec, links)
    }
}

/// What happened to the frames of one episode.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Counts {
    /// Frames pushed before the episode ended.
    pub frames: u64,
    /// Of those, the hand was not tracked.
    pub untracked: u64,
    /// Tracked, but no gesture could be read or the frame joints were collinear.
    pub degenerate: u64,
    /// Control steps whose target IK could not reach (or only on another branch).
    pub unreachable: u64,
    /// Control steps run.
    pub steps: u64,
    /// Frames pushed after the episode ended (ignored).
    pub frames_after_end: u64,
    /// Changes of the smoothed gesture after the first one.
    pub gesture_changes: u64,
    /// Frames per raw gesture class, in the order the classes were first seen.
    pub gestures: Vec<(String, u64)>,
}

/// Why the arm does not move toward the hand in a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NotFollowing {
    /// No usable hand frame yet.
    NoHand,
    /// IK found no solution near the current one.
    Unreachable,
    /// The clutch is released.
    NotEngaged,
}

impl NotFollowing {
    /// The text the page and the tests show.
    pub fn text(self) -> &'static str {
        match self {
            NotFollowing::NoHand => "no hand yet",
            NotFollowing::Unreachable => "target unreachable",
            NotFollowing::NotEngaged => "not engaged",
        }
    }
}

/// One control step: the action chosen from `obs` and what the simulator made of it.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// 0, 1, 2, ... within the episode.
    pub index: u64,
    /// Seconds since the episode's first frame.
    pub t: f64,
    /// The observation the action was chosen from.
    pub obs: Vec<f32>,
    /// The action sent to the simulator.
    pub action: Vec<f32>,
    /// The step's sparse reward.
    pub reward: f32,
    /// The task ended the episode (install, fall).
    pub terminated: bool,
    /// The step limit ended it.
    pub truncated: bool,
    /// `pick` (the first), `install`, `fall`.
    pub events: Vec<&'static str>,
    /// None: the arm moved toward the hand's target.
    pub why: Option<NotFollowing>,
}

/// One hand frame as the session reads it. The gesture is read in the caller (the SVM is
/// Python's): `raw` is this frame's class (None: the model could not read the hand), `gesture`
/// the smoothed one after it (None before any). Both are ignored for an untracked frame.
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// Seconds, any origin, non-decreasing.
    pub t: f64,
    /// The runtime tracked the hand.
    pub tracked: bool,
    /// Joint positions in the session's layout and calibration space.
    pub joints: &'a [[f64; 3]],
    /// This frame's gesture class.
    pub raw: Option<&'a str>,
    /// The smoothed gesture the end effector obeys from now on.
    pub gesture: Option<&'a str>,
    /// A clutch command at this frame (under [`Mapping::Clutch`]).
    pub clutch: Option<ClutchInput>,
}

/// How an episode starts.
#[derive(Debug, Clone)]
pub struct SessionConfig {
    /// The task.
    pub task: Task,
    /// Joint order of the frames.
    pub layout: HandLayout,
    /// The hand that drives.
    pub handedness: Handedness,
    /// Tracking space → Base.
    pub calibration: Calibration,
    /// The simulator seed of the episode (the paper's start of that seed).
    pub seed: u64,
    /// How the hand's pose becomes the tool's target.
    pub mapping: Mapping,
    /// The task spec the episode's env is built from (a researcher's spec file running
    /// `task`'s logic); `None`: `task`'s built-in spec.
    pub spec: Option<Arc<TaskSpec>>,
}

/// One episode of teleoperation (paper §3.2): every hand frame, from a file or live, goes
/// through [`Session::push`], and nothing else drives the robot.
///
/// 1. The wrist / index-proximal / middle-proximal joints, low-pass filtered ([`OneEuro`]),
///    become a tool0 target in Base (`ur3_kin::hand_to_target` through the calibration).
/// 2. Control steps run at the simulator's rate in the hand's own clock: step `k` at
///    `t0 + k·CONTROL_DT`, with every frame up to that time already pushed (each step uses the
///    newest hand state at its start). A frame first runs the steps that fell due before it,
///    then updates the hand state.
/// 3. Per step: IK warm-started from the previous solution and unwrapped next to it (an answer
///    more than [`BRANCH_JUMP`] rad away on a joint is another branch: unreachable), the joint
///    action `clip(wrap(q_ik − q) / joint_step, −1, 1)` (the env's spec's joint step,
///    `TaskSpec::joint_step`), the gesture's command (the suction
///    gets one only when it switches: [`recorded_command`]), one simulator step, one record.
///
/// Frames the pipeline cannot use are counted, never turned into motion: untracked and
/// degenerate frames keep the last target; an unreachable target keeps the last IK solution.
pub struct Session {
    cfg: SessionConfig,
    /// The control period in the hand's clock: tile-sim's `CONTROL_DT` as the decimal it is
    /// written as (0.04 s, not the f32's 0.0399999991), as the page and the hand logs count it.
    dt: f64,
    env: Env,
    obs: Vec<f32>,
    q: [f64; 6],
    q_ik: [f64; 6],
    target: Option<Matrix4<f64>>,
    clutch: Clutch,
    filter: OneEuro<9>,
    counts: Counts,
    t0: Option<f64>,
    t_last: Option<f64>,
    last_tracked: Option<bool>,
    step_index: u64,
    gesture: Option<String>,
    command: (f32, f32),
    last_why: Option<NotFollowing>,
    /// The arm's chain at the simulator's joints now: the one kinematics pass per step besides
    /// the simulator's own (its bodies), shared by the record's `/tf` and the page's frames.
    links: Links,
    picked: bool,
    installed: bool,
    fell: bool,
    terminated: bool,
    truncated: bool,
    total_reward: f64,
}

impl Session {
    /// A session at the start of its episode.
    ///
    /// # Errors
    /// [`TeleopError::SpecTask`] if `cfg.spec` runs another task's logic than `cfg.task`;
    /// the simulator's, if it cannot reset.
    pub fn new(cfg: SessionConfig) -> Result<Session, TeleopError> {
        let mut env = match &cfg.spec {
            Some(spec) if spec.task() != cfg.task => {
                return Err(TeleopError::SpecTask { spec: spec.task().name(), session: cfg.task.name() });
            }
            Some(spec) => Env::from_spec(spec.clone(), 0),
            None => Env::new(cfg.task, 0),
        };
        let obs = env.reset_owned(Some(cfg.seed))?;
        let q = frame_joints(cfg.task, &obs);
        let links = urdf::link_transforms(env.arm(), &env.snapshot().q);
        Ok(Session {
            cfg,
            dt: Constants::get().CONTROL_DT,
            env,
            obs,
            q,
            q_ik: q,
            target: None,
            clutch: Clutch::default(),
            filter: OneEuro::new(1.0, 2.0, 1.0),
            counts: Counts::default(),
            t0: None,
            t_last: None,
            last_tracked: None,
            step_index: 0,
            gesture: None,
            command: (0.0, 0.0),
            last_why: None,
            links,
            picked: false,
            installed: false,
            fell: false,
            terminated: false,
            truncated: false,
            total_reward: 0.0,
        })
    }

    /// The episode has ended (terminated by the task or truncated at its step limit).
    pub fn done(&self) -> bool {
        self.terminated || self.truncated
    }

    /// Feed one hand frame: runs every control step that fell due before it (returned), then
    /// updates the gesture and the target from it. Frames after the episode ended are counted
    /// and ignored.
    ///
    /// # Errors
    /// [`TeleopError`] for a frame of the wrong joint count, non-finite time, an unknown gesture
    /// class, or a failure of the simulator or the recorder.
    pub fn push(
        &mut self,
        f: &Frame<'_>,
        mut rec: Option<&mut dyn Recorder>,
    ) -> Result<Vec<Step>, TeleopError> {
        self.check(f)?;
        let t0 = *self.t0.get_or_insert(f.t);
        let mut steps = Vec::new();
        while !self.done() && self.t_ctrl(t0) < f.t - 1e-9 {
            steps.push(self.control_step(reborrow(&mut rec))?);
        }
        if self.done() {
            self.counts.frames_after_end += 1;
            return Ok(steps);
        }
        self.observe(f, rec)?;
        Ok(steps)
    }

    /// The hand half of [`Session::push`] alone: update the gesture and the target from one
    /// frame (and record it), without running the control steps that fell due.
    ///
    /// # Errors
    /// As [`Session::push`].
    pub fn observe_only(&mut self, f: &Frame<'_>, rec: Option<&mut dyn Recorder>) -> Result<(), TeleopError> {
        self.check(f)?;
        self.t0.get_or_insert(f.t);
        self.observe(f, rec)
    }

    /// The hand stream has ended: run the control steps up to one control period past the last
    /// frame, unless the episode ended before.
    ///
    /// # Errors
    /// The simulator's or the recorder's.
    pub fn finish(&mut self, mut rec: Option<&mut dyn Recorder>) -> Result<Vec<Step>, TeleopError> {
        let mut steps = Vec::new();
        let (Some(t0), Some(t_last)) = (self.t0, self.t_last) else { return Ok(steps) };
        while !self.done() && self.t_ctrl(t0) <= t_last + self.dt {
            steps.push(self.control_step(reborrow(&mut rec))?);
        }
        self.counts.steps = self.step_index;
        Ok(steps)
    }

    /// Use another calibration from the next frame on; `shift` (Base, m) moves the current
    /// target with it (a calibration that differs by a translation moves every target by it).
    pub fn set_calibration(&mut self, calibration: Calibration, shift: Option<[f64; 3]>) {
        self.cfg.calibration = calibration;
        if let (Some(s), Some(t)) = (shift, self.target.as_mut()) {
            for (i, d) in s.iter().enumerate() {
                t[(i, 3)] += d;
            }
        }
    }

    fn check(&self, f: &Frame<'_>) -> Result<(), TeleopError> {
        let expected = self.cfg.layout.joint_count();
        if f.joints.len() != expected {
            return Err(TeleopError::JointCount {
                layout: self.cfg.layout.name(),
                expected,
                got: f.joints.len(),
            });
        }
        if !f.t.is_finite() {
            return Err(TeleopError::Time(f.t));
        }
        if f.tracked
            && let Some(g) = f.gesture
            && command_of(g).is_none()
        {
            return Err(TeleopError::UnknownGesture(g.to_string()));
        }
        Ok(())
    }

    fn t_ctrl(&self, t0: f64) -> f64 {
        t0 + self.step_index as f64 * self.dt
    }

    /// The hand half of [`Session::push`]: the gesture and the target from one frame.
    fn observe(&mut self, f: &Frame<'_>, rec: Option<&mut dyn Recorder>) -> Result<(), TeleopError> {
        let t0 = self.t0.unwrap_or(f.t);
        self.clutch.apply(f.clutch);
        let c = &mut self.counts;
        c.frames += 1;
        self.t_last = Some(f.t);
        self.last_tracked = Some(f.tracked);
        if let Some(r) = rec {
            let frame =
                HandFrame { t: f.t, tracked: f.tracked, joints: f.joints.to_vec(), orientations: None };
            r.hand_frame(&frame, f.t - t0)?;
        }
        if !f.tracked {
            c.untracked += 1;
            return Ok(());
        }
        if f.gesture != self.gesture.as_deref() {
            if self.gesture.is_some() {
                c.gesture_changes += 1;
            }
            self.gesture = f.gesture.map(str::to_string);
            self.command = f.gesture.and_then(command_of).unwrap_or((0.0, 0.0));
        }
        let Some(raw) = f.raw else {
            c.degenerate += 1;
            return Ok(());
        };
        match c.gestures.iter_mut().find(|(g, _)| g == raw) {
            Some((_, n)) => *n += 1,
            None => c.gestures.push((raw.to_string(), 1)),
        }
        let l = self.cfg.layout;
        let (w, i, m) = (f.joints[l.wrist()], f.joints[l.index_proximal()], f.joints[l.middle_proximal()]);
        let p = self.filter.filter([w[0], w[1], w[2], i[0], i[1], i[2], m[0], m[1], m[2]], f.t);
        let hand = HandPoints::new([p[0], p[1], p[2]], [p[3], p[4], p[5]], [p[6], p[7], p[8]]);
        let Ok(h) = ur3_kin::hand_to_target(&hand, self.cfg.handedness, &self.cfg.calibration) else {
            c.degenerate += 1; // collinear frame joints
            return Ok(());
        };
        match self.cfg.mapping {
            Mapping::Absolute => self.target = Some(h.to_homogeneous()),
            Mapping::Clutch => {
                let (q_ik, arm) = (self.q_ik, self.env.arm());
                if let Some(t) = self.clutch.target(&h, || ur3_kin::fk(arm, &q_ik)) {
                    self.target = Some(t.to_homogeneous());
                }
            }
        }
        Ok(())
    }

    fn control_step(&mut self, rec: Option<&mut dyn Recorder>) -> Result<Step, TeleopError> {
        let task = self.cfg.task;
        let mut a = vec![0.0f32; task.act_dim()];
        let mut why = None;
        match self.target {
            None => why = Some(NotFollowing::NoHand),
            Some(target) => {
                match self.next_joints(&target) {
                    Ok(d) => self.q_ik = std::array::from_fn(|i| self.q_ik[i] + d[i]),
                    Err(w) => {
                        if w == NotFollowing::Unreachable {
                            self.counts.unreachable += 1;
                        }
                        why = Some(w);
                    }
                }
                let ja = tile_sim::action::action_toward(self.env.spec(), &self.q, &self.q_ik);
                for (ai, v) in a.iter_mut().zip(ja) {
                    *ai = v as f32;
                }
            }
        }
        let fd = task.obs_frame_dim();
        let frame = &self.obs[self.obs.len() - fd..];
        let (cmd, spin) = self.command;
        a[6] = recorded_command(task, cmd, frame);
        if task.act_dim() == 8 {
            a[7] = spin;
        }
        let t0 = self.t0.unwrap_or(0.0);
        let t = self.t_ctrl(t0) - t0;
        let (obs, out, _) = self.env.step_owned(&a)?;
        let obs_before = std::mem::replace(&mut self.obs, obs);
        self.q = frame_joints(task, &self.obs);
        let mut events = Vec::new();
        if out.picked && !self.picked {
            events.push("pick");
        }
        if out.installed {
            events.push("install");
        }
        if out.fell {
            events.push("fall");
        }
        self.picked |= out.picked;
        self.installed |= out.installed;
        self.fell |= out.fell;
        (self.terminated, self.truncated) = (out.terminated, out.truncated);
        self.total_reward += f64::from(out.reward);
        let step = Step {
            index: self.step_index,
            t,
            obs: obs_before,
            action: a,
            reward: out.reward,
            terminated: out.terminated,
            truncated: out.truncated,
            events,
            why,
        };
        let snap = self.env.snapshot();
        self.links = urdf::link_transforms(self.env.arm(), &snap.q);
        if let Some(r) = rec {
            r.step(&self.record(&step, &snap), &self.links)?;
        }
        self.last_why = why;
        self.step_index += 1;
        self.counts.steps = self.step_index;
        Ok(step)
    }

    /// This step's change of the IK answer toward `target`, wrapped. Absolute: IK of the target
    /// itself. Clutch: IK of the commanded pose one bounded step toward it (kept on success).
    fn next_joints(&mut self, target: &Matrix4<f64>) -> Result<[f64; 6], NotFollowing> {
        let pose = ur3_kin::pose_from_matrix(target).map_err(|_| NotFollowing::Unreachable)?;
        if self.cfg.mapping == Mapping::Absolute {
            return self.solve(&pose).ok_or(NotFollowing::Unreachable);
        }
        if !self.clutch.engaged() {
            return Err(NotFollowing::NotEngaged);
        }
        let c = self.clutch.next(&pose);
        let d = self.solve(&c).ok_or(NotFollowing::Unreachable)?;
        self.clutch.commit(c);
        Ok(d)
    }

    /// The IK answer's change from the last one, wrapped; None: unreachable or another branch.
    fn solve(&self, pose: &ur3_kin::Pose) -> Option<[f64; 6]> {
        let opts = IkOptions::with_tol(None).ok()?;
        let sol = ur3_kin::ik(self.env.arm(), pose, Some(&self.q_ik), &opts).ok()?;
        let d: [f64; 6] = std::array::from_fn(|i| wrap_to_pi(sol[i] - self.q_ik[i]));
        let jump = d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        (jump <= BRANCH_JUMP).then_some(d)
    }

    fn record(&self, step: &Step, s: &Snapshot) -> StepRecord {
        StepRecord {
            step: step.index,
            t: step.t,
            obs: step.obs.clone(),
            action: step.action.clone(),
            reward: f64::from(step.reward),
            terminated: step.terminated,
            truncated: step.truncated,
            gesture: self.gesture.clone().unwrap_or_default(),
            joints: s.q,
            ee_pose: RecPose { position: s.tool0.t, orientation: s.tool0.q },
            tile_pose: RecPose { position: s.object.t, orientation: s.object.q },
            row_poses: s
                .row
                .iter()
                .map(|r| RecPose { position: r.object.t, orientation: r.object.q })
                .collect(),
            events: step.events.iter().map(|e| (*e).to_string()).collect(),
            scene: Vec::new(),
        }
    }

    // ------------------------------------------------------------------ state

    /// The configuration the episode runs with (its calibration as last set).
    pub fn config(&self) -> &SessionConfig {
        &self.cfg
    }
    /// What happened to the frames so far.
    pub fn counts(&self) -> &Counts {
        &self.counts
    }
    /// The tool0 target in Base of the newest usable frame, as a 4×4 matrix.
    pub fn target(&self) -> Option<&Matrix4<f64>> {
        self.target.as_ref()
    }
    /// [`Session::target`] as a pose (position and quaternion).
    pub fn target_pose(&self) -> Option<RecPose> {
        let m = self.target.as_ref()?;
        ur3_kin::pose_from_matrix(m).ok().map(|p| RecPose::from_isometry(&p))
    }
    /// The clutch is engaged (always false under [`Mapping::Absolute`]).
    pub fn engaged(&self) -> bool {
        self.clutch.engaged()
    }
    /// The smoothed gesture the end effector obeys.
    pub fn gesture(&self) -> Option<&str> {
        self.gesture.as_deref()
    }
    /// The end-effector command and spin of the smoothed gesture ((0, 0) before any).
    pub fn command(&self) -> (f32, f32) {
        self.command
    }
    /// Control steps run.
    pub fn step_index(&self) -> u64 {
        self.step_index
    }
    /// Why the newest step did not follow (None: it did, or no step yet).
    pub fn last_why(&self) -> Option<NotFollowing> {
        self.last_why
    }
    /// The newest frame's tracked flag (None before any frame).
    pub fn last_tracked(&self) -> Option<bool> {
        self.last_tracked
    }
    /// The newest observation.
    pub fn observation(&self) -> &[f32] {
        &self.obs
    }
    /// The simulator's state now.
    pub fn snapshot(&self) -> Snapshot {
        self.env.snapshot()
    }
    /// Poses in Base (`[x, y, z, qx, qy, qz, qw]`) of every frame the scene's entities are locked
    /// to (the URDF links `shoulder_link` … `tool0`, `tile`, and a row's `tile_0` …), from the step's one pass down
    /// the arm's chain.
    pub fn frame_numbers(&self) -> BTreeMap<&'static str, [f64; 7]> {
        compose(&self.links, &self.env.snapshot())
    }
    /// The simulator.
    pub fn env(&self) -> &Env {
        &self.env
    }
    /// Test/tool API: teleport the arm (`Env::set_joints`); the session's own joints follow at
    /// the next step's observation.
    ///
    /// # Errors
    /// The simulator's, for angles that are not finite or beyond ±π.
    pub fn set_joints(&mut self, q: [f64; 6]) -> Result<(), TeleopError> {
        self.env.set_joints(q)?;
        self.links = urdf::link_transforms(self.env.arm(), &self.env.snapshot().q);
        Ok(())
    }
    /// Picked, installed, fell (ever this episode); terminated, truncated; total reward.
    pub fn outcome(&self) -> Outcome {
        Outcome {
            steps: self.step_index,
            picked: self.picked,
            installed: self.installed,
            fell: self.fell,
            terminated: self.terminated,
            truncated: self.truncated,
            total_reward: self.total_reward,
        }
    }
}

/// How an episode went, so far or in the end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    pub steps: u64,
    pub picked: bool,
    pub installed: bool,
    pub fell: bool,
    pub terminated: bool,
    pub truncated: bool,
    pub total_reward: f64,
}

/// A shorter-lived handle on the recorder, for one call.
fn reborrow<'b>(rec: &'b mut Option<&mut dyn Recorder>) -> Option<&'b mut dyn Recorder> {
    match rec {
        Some(r) => Some(&mut **r),
        None => None,
    }
}

/// The arm's joints in the newest observation frame (f32, as the policy sees them).
fn frame_joints(task: Task, obs: &[f32]) -> [f64; 6] {
    let frame = &obs[obs.len() - task.obs_frame_dim()..];
    std::array::from_fn(|i| f64::from(frame[i]))
}

/// Poses in Base of the frames the page's scene entities are locked to, as demo-log's
/// `frame_numbers` gives them: the URDF links composed down the chain from `base`, then the tile,
/// then a row's tiles.
fn compose(links: &Links, s: &Snapshot) -> BTreeMap<&'static str, [f64; 7]> {
    let mut acc = ur3_kin::Pose::identity();
    let mut out: BTreeMap<&'static str, [f64; 7]> = links
        .iter()
        .map(|(_, child, rel)| {
            acc *= rel;
            (*child, RecPose::from_isometry(&acc).to_numbers())
        })
        .collect();
    let tile = RecPose { position: s.object.t, orientation: s.object.q };
    out.insert(demo_log::TILE_FRAME, tile.to_numbers());
    for (frame, r) in demo_log::ROW_FRAMES.into_iter().zip(&s.row) {
        out.insert(frame, RecPose { position: r.object.t, orientation: r.object.q }.to_numbers());
    }
    out
}
