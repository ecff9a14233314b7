//! The stepping calls with owned outputs, for callers that hand each result away (the Python
//! binding): the observation comes back as a new `Vec` instead of filling a caller's buffer,
//! and a step's facts and the recorder's state come as serializable records.

use crate::{Env, PoseRec, SimError, Snapshot, StepOutcome, VecEnv, VecEnvState};

/// A step's facts as `SimEnv.step` reports them (its `info`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct StepInfo {
    pub picked: bool,
    pub held: bool,
    pub installed: bool,
    pub fell: bool,
    /// Steps taken in this episode, this one included.
    pub step: u32,
}

/// What a demo recorder reads after a step: the [`Snapshot`] and the arm's DH frames 0..=6
/// ([`Env::link_poses`]), serialized as one flat record (the snapshot's keys, then `links`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct RecordState {
    #[serde(flatten)]
    pub snapshot: Snapshot,
    pub links: [PoseRec; 7],
}

impl Env {
    /// [`Env::reset`] → the first observation (`obs_dim`).
    pub fn reset_owned(&mut self, seed: Option<u64>) -> Result<Vec<f32>, SimError> {
        let mut obs = vec![0.0; self.task().obs_dim()];
        self.reset(seed, &mut obs).map(|()| obs)
    }

    /// [`Env::step`] → (observation, outcome, [`StepInfo`]).
    pub fn step_owned(&mut self, action: &[f32]) -> Result<(Vec<f32>, StepOutcome, StepInfo), SimError> {
        let mut obs = vec![0.0; self.task().obs_dim()];
        let o = self.step(action, &mut obs)?;
        let step = self.snapshot().step;
        Ok((obs, o, StepInfo { picked: o.picked, held: o.held, installed: o.installed, fell: o.fell, step }))
    }

    /// The snapshot and the arm's frames now.
    pub fn record_state(&self) -> RecordState {
        RecordState { snapshot: self.snapshot(), links: self.link_poses() }
    }
}

impl VecEnv {
    fn obs_buffer(&self, envs: usize) -> Vec<f32> {
        vec![0.0; envs * self.task().obs_dim()]
    }

    /// [`VecEnv::reset`] → the observations (`num_envs × obs_dim`, row-major).
    pub fn reset_owned(&mut self, seed: Option<u64>) -> Result<Vec<f32>, SimError> {
        let mut obs = self.obs_buffer(self.num_envs());
        self.reset(seed, &mut obs).map(|()| obs)
    }

    /// [`VecEnv::reset_mask`] → the observations of all envs.
    pub fn reset_mask_owned(&mut self, mask: &[bool]) -> Result<Vec<f32>, SimError> {
        let mut obs = self.obs_buffer(self.num_envs());
        self.reset_mask(mask, &mut obs).map(|()| obs)
    }

    /// [`VecEnv::reset_replay`] → env `i`'s observation (`obs_dim`).
    pub fn reset_replay_owned(
        &mut self,
        i: usize,
        seed: u64,
        start: Option<crate::Start>,
        actions: &[f32],
    ) -> Result<Vec<f32>, SimError> {
        let mut obs = self.obs_buffer(1);
        self.reset_replay(i, seed, start, actions, &mut obs).map(|_| obs)
    }

    /// [`VecEnv::reset_starts`] → the observations of all envs.
    pub fn reset_starts_owned(&mut self, seed: u64, starts: &[crate::Start]) -> Result<Vec<f32>, SimError> {
        let mut obs = self.obs_buffer(self.num_envs());
        self.reset_starts(seed, starts, &mut obs).map(|()| obs)
    }

    /// [`VecEnv::restore`] → the observations of all envs.
    pub fn restore_owned(&mut self, state: &VecEnvState) -> Result<Vec<f32>, SimError> {
        let mut obs = self.obs_buffer(self.num_envs());
        self.restore(state, &mut obs).map(|()| obs)
    }
}

impl crate::Variation {
    /// The variation a caller names: `"training"` (the paper's, [`Variation::default`](crate::Variation::default)),
    /// `"robust"` or `"wide"`; `None` for another name.
    pub fn named(name: &str) -> Option<crate::Variation> {
        crate::Variation::named_in(name, &crate::TaskSpec::builtin(crate::Task::TileSuction))
    }

    /// [`Variation::named`](crate::Variation::named) of the task `spec` describes: its
    /// `starts.paper`, the robust widening of that, its `starts.wide`.
    pub fn named_in(name: &str, spec: &crate::TaskSpec) -> Option<crate::Variation> {
        let paper = spec.starts.paper.variation();
        match name {
            "training" | "paper" => Some(paper),
            "robust" => Some(crate::Variation::robust_of(paper)),
            "wide" => Some(spec.starts.wide.variation()),
            _ => None,
        }
    }

    /// The variation a caller names by options: [`Variation::robust`](crate::Variation::robust)
    /// when `robust`, else the object's x range `object_x` (default: the paper's) and the
    /// target's jitter (m).
    pub fn from_options(object_x: Option<[f32; 2]>, target_jitter: f32, robust: bool) -> crate::Variation {
        let spec = crate::TaskSpec::builtin(crate::Task::TileSuction);
        crate::Variation::from_options_in(object_x, target_jitter, robust, &spec)
    }

    /// [`Variation::from_options`](crate::Variation::from_options) about `spec`'s paper starts.
    pub fn from_options_in(
        object_x: Option<[f32; 2]>,
        target_jitter: f32,
        robust: bool,
        spec: &crate::TaskSpec,
    ) -> crate::Variation {
        let paper = spec.starts.paper.variation();
        match (robust, object_x) {
            (true, _) => crate::Variation::robust_of(paper),
            (false, Some(x)) => crate::Variation { object_x: x, target_jitter, ..paper },
            (false, None) => crate::Variation { target_jitter, ..paper },
        }
    }
}
