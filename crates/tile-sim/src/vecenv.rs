//! N environments stepped in one call across `std::thread::scope` threads, with same-step
//! auto-reset (the terminal observation is kept in `final_obs`).
//!
//! **Seeds.** Every episode's seed is a pure function of the VecEnv's base seed, the env index
//! and how many episodes that env has started since the base was set ([`episode_seed`]): the
//! base is set by [`VecEnv::new`] and [`VecEnv::reset`], which also zero the episode counts;
//! auto-resets and [`VecEnv::reset_mask`] start episode `count + 1` of their env. So a VecEnv
//! reset with seed `s` follows the same trajectories, auto-resets included, as a fresh one reset
//! with `s`, whatever it did before (gymnasium's reproducibility contract).
//!
//! **State.** The VecEnv also records the actions of each env's running episode, so
//! [`VecEnv::state`] (base seed, episode counts, those actions: plain numbers) rebuilds it
//! exactly with [`VecEnv::restore`], which replays them (the simulator is deterministic). A
//! trainer checkpoints this and resumes bit for bit without cutting episodes.

use crate::env::{Env, StepOutcome, check_action};
use crate::pool::Pool;
use crate::spec::TaskSpec;
use crate::starts::Start;
use crate::{SimError, Task};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::{Arc, Mutex};

/// Envs per work block handed to a stepping thread.
const BLOCK: usize = 4;

/// Caller-owned output slices of one [`VecEnv::step`]. Row `i` belongs to env `i`.
/// `obs`/`final_obs`: `num_envs × obs_dim` (row-major); the others `num_envs`.
pub struct StepOut<'a> {
    /// Observation after the step; for an env that ended this step, the first observation of
    /// its new episode (same-step auto-reset).
    pub obs: &'a mut [f32],
    pub reward: &'a mut [f32],
    pub terminated: &'a mut [bool],
    pub truncated: &'a mut [bool],
    /// Terminal observation of envs that ended this step; the rows of the other envs are zeros.
    pub final_obs: &'a mut [f32],
    /// Row `i` of `final_obs` is valid (env `i` ended this step).
    pub has_final: &'a mut [bool],
    /// Picked ever during the episode (of the ended episode for envs that ended this step).
    pub picked: &'a mut [bool],
    /// Success event this step.
    pub installed: &'a mut [bool],
    /// Failure event this step.
    pub fell: &'a mut [bool],
}

/// Owned output buffers for [`VecEnv::step_buffers`].
#[derive(Debug, Clone)]
pub struct StepBuffers {
    pub obs: Vec<f32>,
    pub reward: Vec<f32>,
    pub terminated: Vec<bool>,
    pub truncated: Vec<bool>,
    pub final_obs: Vec<f32>,
    pub has_final: Vec<bool>,
    pub picked: Vec<bool>,
    pub installed: Vec<bool>,
    pub fell: Vec<bool>,
}

impl StepBuffers {
    /// Buffers sized for `num_envs` envs of `task`.
    pub fn new(task: Task, num_envs: usize) -> StepBuffers {
        let od = task.obs_dim();
        StepBuffers {
            obs: vec![0.0; num_envs * od],
            reward: vec![0.0; num_envs],
            terminated: vec![false; num_envs],
            truncated: vec![false; num_envs],
            final_obs: vec![0.0; num_envs * od],
            has_final: vec![false; num_envs],
            picked: vec![false; num_envs],
            installed: vec![false; num_envs],
            fell: vec![false; num_envs],
        }
    }

    /// Borrow as [`StepOut`].
    pub fn as_out(&mut self) -> StepOut<'_> {
        StepOut {
            obs: &mut self.obs,
            reward: &mut self.reward,
            terminated: &mut self.terminated,
            truncated: &mut self.truncated,
            final_obs: &mut self.final_obs,
            has_final: &mut self.has_final,
            picked: &mut self.picked,
            installed: &mut self.installed,
            fell: &mut self.fell,
        }
    }
}

/// SplitMix64's output function of `x + γ` (a bijection of u64, good avalanche).
fn mix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of episode `episode` (0 = the one started by `new`/`reset`) of env `env` of a
/// VecEnv whose base seed is `base`:
///
/// * `episode == 0`: `base + env` (wrapping), as [`VecEnv::reset`] has always documented;
/// * `episode >= 1`: `mix(mix(mix(base) + env) + episode)` (wrapping adds), with `mix` the
///   SplitMix64 output function of `x + 0x9E3779B97F4A7C15`.
///
/// A pure function: no hidden RNG is involved in any episode a VecEnv starts.
pub fn episode_seed(base: u64, env: u64, episode: u64) -> u64 {
    if episode == 0 {
        base.wrapping_add(env)
    } else {
        mix(mix(mix(base).wrapping_add(env)).wrapping_add(episode))
    }
}

/// Everything that determines a [`VecEnv`]'s future given its actions: plain numbers that a
/// checkpoint can store ([`VecEnv::state`], [`VecEnv::restore`]).
#[derive(Debug, Clone, PartialEq)]
pub struct VecEnvState {
    /// The base seed of [`episode_seed`].
    pub base_seed: u64,
    /// Per env: the index of its running episode (episodes started since the base was set − 1).
    pub episodes: Vec<u64>,
    /// Per env: the seed of its running episode ([`episode_seed`], or the demo's seed of a
    /// [`VecEnv::reset_replay`] start).
    pub seeds: Vec<u64>,
    /// Per env: where its running episode started (drawn from the seed under the variation of
    /// that moment, or given), so a restore does not depend on the variation set at restore time.
    pub starts: Vec<Start>,
    /// Per env: the actions (`act_dim` each, row-major, as passed to `step`) of its running
    /// episode, fewer than the spec's `episode.max_steps` rows.
    pub actions: Vec<Vec<f32>>,
}

/// A batch of envs of one task.
pub struct VecEnv {
    task: Task,
    spec: Arc<TaskSpec>,
    envs: Vec<Env>,
    num_threads: usize,
    pool: Pool,
    rng: ChaCha8Rng,
    base_seed: u64,
    episodes: Vec<u64>,
    logs: Vec<Vec<f32>>,
}

impl VecEnv {
    /// `num_envs` envs (≥ 1) of `task` with base seed `seed`: the state `reset(Some(seed))`
    /// gives (env `i` in episode `seed + i`). Steps use `num_threads` threads (clamped to
    /// 1..=num_envs): the caller plus `num_threads − 1` persistent worker threads owned by the
    /// VecEnv (1 = no extra threads).
    pub fn new(task: Task, num_envs: usize, seed: u64, num_threads: usize) -> Result<VecEnv, SimError> {
        VecEnv::from_spec(TaskSpec::builtin(task), num_envs, seed, num_threads)
    }

    /// [`VecEnv::new`] for the task `spec` describes ([`Env::from_spec`]).
    pub fn from_spec(
        spec: Arc<TaskSpec>,
        num_envs: usize,
        seed: u64,
        num_threads: usize,
    ) -> Result<VecEnv, SimError> {
        if num_envs == 0 {
            return Err(SimError::InvalidArgument("num_envs must be at least 1".into()));
        }
        let task = spec.task();
        let mut envs: Vec<Env> =
            (0..num_envs).map(|i| Env::from_spec(Arc::clone(&spec), seed.wrapping_add(i as u64))).collect();
        let mut o = vec![0.0; task.obs_dim()];
        for (i, env) in envs.iter_mut().enumerate() {
            env.reset(Some(episode_seed(seed, i as u64, 0)), &mut o)?;
        }
        let num_threads = num_threads.clamp(1, num_envs);
        let log_cap = spec.episode.max_steps as usize * task.act_dim();
        Ok(VecEnv {
            task,
            spec,
            envs,
            num_threads,
            pool: Pool::new(num_threads - 1),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_0F5E_ED00),
            base_seed: seed,
            episodes: vec![0; num_envs],
            logs: (0..num_envs).map(|_| Vec::with_capacity(log_cap)).collect(),
        })
    }

    /// How every env's episodes start from the next reset on ([`Variation`]); refused (and
    /// nothing changed) if out of range. Not part of [`VecEnv::state`] (each running episode's start is); a restore keeps it.
    pub fn set_variation(&mut self, v: crate::Variation) -> Result<(), SimError> {
        for env in &self.envs {
            v.validate_for(env.arm())?;
        }
        for env in &mut self.envs {
            env.set_variation(v)?;
        }
        Ok(())
    }

    pub fn task(&self) -> Task {
        self.task
    }

    /// The spec every env runs.
    pub fn spec(&self) -> &Arc<TaskSpec> {
        &self.spec
    }

    pub fn num_envs(&self) -> usize {
        self.envs.len()
    }

    pub fn num_threads(&self) -> usize {
        self.num_threads
    }

    /// Change the number of stepping threads (clamped to 1..=num_envs).
    pub fn set_num_threads(&mut self, n: usize) {
        self.num_threads = n.clamp(1, self.envs.len());
        if self.pool.workers() != self.num_threads - 1 {
            self.pool = Pool::new(self.num_threads - 1);
        }
    }

    /// Borrow env `i` (for snapshots and scenes).
    pub fn env(&self, i: usize) -> Option<&Env> {
        self.envs.get(i)
    }

    /// Mutable borrow of env `i` (test/tool API: `set_joints`, ...).
    pub fn env_mut(&mut self, i: usize) -> Option<&mut Env> {
        self.envs.get_mut(i)
    }

    /// Reset every env and set the base seed: `Some(s)` or, with `None`, the next draw of the
    /// VecEnv's own RNG ([`VecEnv::next_seed`]). Episode counts restart at 0, so env `i` starts
    /// episode `s + i` and its later episodes follow [`episode_seed`]. Writes
    /// `num_envs × obs_dim` floats.
    pub fn reset(&mut self, seed: Option<u64>, obs_out: &mut [f32]) -> Result<(), SimError> {
        let od = self.task.obs_dim();
        check("obs", self.envs.len() * od, obs_out.len())?;
        let base = seed.unwrap_or_else(|| self.rng.next_u64());
        self.base_seed = base;
        for (i, (env, o)) in self.envs.iter_mut().zip(obs_out.chunks_mut(od)).enumerate() {
            env.reset(Some(episode_seed(base, i as u64, 0)), o)?;
            self.episodes[i] = 0;
            self.logs[i].clear();
        }
        Ok(())
    }

    /// Reset every env as [`VecEnv::reset`] with `Some(seed)` does, but env `i` starts at
    /// `starts[i]` (each [`Start::check`]ed first: on error nothing changes). Later episodes
    /// draw their starts from the variation again.
    pub fn reset_starts(&mut self, seed: u64, starts: &[Start], obs_out: &mut [f32]) -> Result<(), SimError> {
        let od = self.task.obs_dim();
        check("obs", self.envs.len() * od, obs_out.len())?;
        check("starts", self.envs.len(), starts.len())?;
        for (i, st) in starts.iter().enumerate() {
            st.check(self.task).map_err(|e| match e {
                SimError::InvalidArgument(m) => SimError::InvalidArgument(format!("env {i}: {m}")),
                e => e,
            })?;
        }
        self.base_seed = seed;
        for (i, ((env, o), st)) in self.envs.iter_mut().zip(obs_out.chunks_mut(od)).zip(starts).enumerate() {
            env.reset_start(*st, episode_seed(seed, i as u64, 0), o)?;
            self.episodes[i] = 0;
            self.logs[i].clear();
        }
        Ok(())
    }

    /// Reset the envs whose mask entry is true (each starts its next episode, seeded by
    /// [`episode_seed`]); the rows of the others in `obs_out` are filled with their current
    /// observation.
    pub fn reset_mask(&mut self, mask: &[bool], obs_out: &mut [f32]) -> Result<(), SimError> {
        let od = self.task.obs_dim();
        check("mask", self.envs.len(), mask.len())?;
        check("obs", self.envs.len() * od, obs_out.len())?;
        for (i, ((env, o), &m)) in self.envs.iter_mut().zip(obs_out.chunks_mut(od)).zip(mask).enumerate() {
            if m {
                self.episodes[i] += 1;
                self.logs[i].clear();
                env.reset(Some(episode_seed(self.base_seed, i as u64, self.episodes[i])), o)?;
            } else {
                o.copy_from_slice(env.observation());
            }
        }
        Ok(())
    }

    /// Reset env `i` to episode `seed` (at `start`, or the paper's start of `seed`) and replay
    /// `actions` in it ([`Env::reset_replay`]); the other envs do not move. Writes env `i`'s
    /// observation (`obs_dim` floats) into `obs_out`.
    pub fn reset_replay(
        &mut self,
        i: usize,
        seed: u64,
        start: Option<Start>,
        actions: &[f32],
        obs_out: &mut [f32],
    ) -> Result<usize, SimError> {
        let n = self.envs.len();
        let env = self
            .envs
            .get_mut(i)
            .ok_or_else(|| SimError::InvalidArgument(format!("env index {i} out of range (num_envs {n})")))?;
        let steps = env.reset_replay(seed, start, actions, obs_out)?;
        // a new episode of env i: counted, and its actions so far are the replayed ones (so
        // `state`/`restore` rebuild it from its own seed)
        self.episodes[i] += 1;
        self.logs[i].clear();
        self.logs[i].extend_from_slice(actions);
        Ok(steps)
    }

    /// Draw a fresh base seed from the VecEnv's own RNG (what `reset(None)` uses).
    pub fn next_seed(&mut self) -> u64 {
        self.rng.next_u64()
    }

    /// The base seed, episode counts and running episodes' actions (see [`VecEnvState`]).
    /// Teleports through [`VecEnv::env_mut`] are not part of it.
    pub fn state(&self) -> VecEnvState {
        VecEnvState {
            base_seed: self.base_seed,
            episodes: self.episodes.clone(),
            seeds: self.envs.iter().map(Env::episode_seed).collect(),
            starts: self.envs.iter().map(Env::start).collect(),
            actions: self.logs.clone(),
        }
    }

    /// Rebuild the envs from `state`: each env restarts its running episode and replays its
    /// actions. Writes the observations (`num_envs × obs_dim`), which equal those the VecEnv
    /// had when `state` was taken. Errors (nothing changed): sizes that do not fit this VecEnv,
    /// invalid actions, or actions that end the episode (a state from another simulator).
    pub fn restore(&mut self, state: &VecEnvState, obs_out: &mut [f32]) -> Result<(), SimError> {
        let (n, ad, od) = (self.envs.len(), self.task.act_dim(), self.task.obs_dim());
        let max_steps = self.spec.episode.max_steps as usize;
        check("obs", n * od, obs_out.len())?;
        check("episodes", n, state.episodes.len())?;
        check("seeds", n, state.seeds.len())?;
        check("starts", n, state.starts.len())?;
        check("actions", n, state.actions.len())?;
        for (i, a) in state.actions.iter().enumerate() {
            if a.len() % ad != 0 || a.len() / ad >= max_steps {
                return Err(SimError::InvalidArgument(format!(
                    "env {i}: {} action numbers, expected a multiple of {ad} below {}",
                    a.len(),
                    max_steps * ad
                )));
            }
            for row in a.chunks(ad) {
                check_action(self.task, row)?;
            }
        }
        // Replay into fresh envs first, so a state that does not replay leaves `self` unchanged.
        let mut envs = Vec::with_capacity(n);
        for (i, (a, o)) in state.actions.iter().zip(obs_out.chunks_mut(od)).enumerate() {
            let mut env = Env::from_spec(Arc::clone(&self.spec), 0);
            env.set_variation(self.envs[i].variation())?;
            env.reset_start_unchecked(state.starts[i], state.seeds[i], o);
            for (k, row) in a.chunks(ad).enumerate() {
                let r = env.step(row, o)?;
                if r.terminated || r.truncated {
                    return Err(SimError::InvalidArgument(format!(
                        "env {i}: the recorded episode ends at action {k} of {}; the state was \
                         not taken from this simulator",
                        a.len() / ad
                    )));
                }
            }
            envs.push(env);
        }
        for (i, (slot, env)) in self.envs.iter_mut().zip(envs).enumerate() {
            *slot = env;
            self.logs[i].clear();
            self.logs[i].extend_from_slice(&state.actions[i]);
        }
        self.base_seed = state.base_seed;
        self.episodes.copy_from_slice(&state.episodes);
        Ok(())
    }

    /// Step every env with its row of `actions` (`num_envs × act_dim`, row-major). Envs that end
    /// (terminated or truncated) are reset in the same call. All actions are validated before any
    /// env moves; on error nothing changes. No allocation apart from the world rebuild of an
    /// env that resets.
    pub fn step(&mut self, actions: &[f32], out: StepOut<'_>) -> Result<(), SimError> {
        let n = self.envs.len();
        let ad = self.task.act_dim();
        let od = self.task.obs_dim();
        check("actions", n * ad, actions.len())?;
        check("obs", n * od, out.obs.len())?;
        check("final_obs", n * od, out.final_obs.len())?;
        for (what, len) in [
            ("reward", out.reward.len()),
            ("terminated", out.terminated.len()),
            ("truncated", out.truncated.len()),
            ("has_final", out.has_final.len()),
            ("picked", out.picked.len()),
            ("installed", out.installed.len()),
            ("fell", out.fell.len()),
        ] {
            check(what, n, len)?;
        }
        for row in actions.chunks(ad) {
            check_action(self.task, row)?;
        }
        // Small blocks handed out dynamically: a thread that gets less CPU (shared machine) just
        // takes fewer blocks, so the call never waits on a starved thread's fixed share.
        let chunk = if self.num_threads == 1 { n } else { BLOCK.min(n.div_ceil(self.num_threads)) };
        let StepOut { obs, reward, terminated, truncated, final_obs, has_final, picked, installed, fell } =
            out;
        let base = self.base_seed;
        let parts = self
            .envs
            .chunks_mut(chunk)
            .zip(self.episodes.chunks_mut(chunk))
            .zip(self.logs.chunks_mut(chunk))
            .enumerate()
            .zip(actions.chunks(chunk * ad))
            .zip(obs.chunks_mut(chunk * od))
            .zip(final_obs.chunks_mut(chunk * od))
            .zip(reward.chunks_mut(chunk))
            .zip(terminated.chunks_mut(chunk))
            .zip(truncated.chunks_mut(chunk))
            .zip(has_final.chunks_mut(chunk))
            .zip(picked.chunks_mut(chunk))
            .zip(installed.chunks_mut(chunk))
            .zip(fell.chunks_mut(chunk))
            .map(|(((((((((((b, ((e, ep), lg)), a), o), fo), r), te), tr), hf), pk), ins), fl)| Part {
                first: b * chunk,
                base,
                envs: e,
                episodes: ep,
                logs: lg,
                actions: a,
                obs: o,
                final_obs: fo,
                reward: r,
                terminated: te,
                truncated: tr,
                has_final: hf,
                picked: pk,
                installed: ins,
                fell: fl,
            });
        if self.num_threads == 1 {
            for p in parts {
                p.run(ad, od);
            }
        } else {
            let queue = Mutex::new(parts);
            let work = || {
                loop {
                    // Poisoning cannot happen (Part::run does not panic on valid input); recover anyway.
                    let next = queue.lock().unwrap_or_else(|e| e.into_inner()).next();
                    match next {
                        Some(p) => p.run(ad, od),
                        None => break,
                    }
                }
            };
            self.pool.run(&work);
        }
        Ok(())
    }

    /// Convenience: step into owned [`StepBuffers`].
    pub fn step_buffers(&mut self, actions: &[f32], buf: &mut StepBuffers) -> Result<(), SimError> {
        self.step(actions, buf.as_out())
    }
}

struct Part<'a> {
    /// Index of `envs[0]` in the VecEnv.
    first: usize,
    base: u64,
    envs: &'a mut [Env],
    episodes: &'a mut [u64],
    logs: &'a mut [Vec<f32>],
    actions: &'a [f32],
    obs: &'a mut [f32],
    final_obs: &'a mut [f32],
    reward: &'a mut [f32],
    terminated: &'a mut [bool],
    truncated: &'a mut [bool],
    has_final: &'a mut [bool],
    picked: &'a mut [bool],
    installed: &'a mut [bool],
    fell: &'a mut [bool],
}

impl Part<'_> {
    fn run(self, ad: usize, od: usize) {
        for (i, env) in self.envs.iter_mut().enumerate() {
            let a = &self.actions[i * ad..(i + 1) * ad];
            // Capacity `episode.max_steps` rows: an episode never holds more, so no allocation.
            self.logs[i].extend_from_slice(a);
            let o: StepOutcome = env.step_unchecked(a);
            self.reward[i] = o.reward;
            self.terminated[i] = o.terminated;
            self.truncated[i] = o.truncated;
            self.picked[i] = o.picked;
            self.installed[i] = o.installed;
            self.fell[i] = o.fell;
            let row = &mut self.obs[i * od..(i + 1) * od];
            if o.terminated || o.truncated {
                self.has_final[i] = true;
                self.final_obs[i * od..(i + 1) * od].copy_from_slice(env.observation());
                self.episodes[i] += 1;
                self.logs[i].clear();
                let seed = episode_seed(self.base, (self.first + i) as u64, self.episodes[i]);
                // Infallible: the row has the right length.
                let _ = env.reset(Some(seed), row);
            } else {
                self.has_final[i] = false;
                // The final-observation rule: rows of envs that did not end are zeros, never a
                // stale terminal observation of an earlier step.
                self.final_obs[i * od..(i + 1) * od].fill(0.0);
                row.copy_from_slice(env.observation());
            }
        }
    }
}

fn check(what: &'static str, expected: usize, got: usize) -> Result<(), SimError> {
    if expected != got {
        return Err(SimError::BufferShape { what, expected, got });
    }
    Ok(())
}
