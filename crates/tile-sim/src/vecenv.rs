//! N environments stepped in one call across `std::thread::scope` threads, with same-step
//! auto-reset (the terminal observation is kept in `final_obs`).

use crate::env::{Env, StepOutcome, check_action};
use crate::pool::Pool;
use crate::{SimError, Task};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Mutex;

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
    /// Terminal observation of envs that ended this step (rows of other envs are left untouched).
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

/// A batch of envs of one task.
pub struct VecEnv {
    task: Task,
    envs: Vec<Env>,
    num_threads: usize,
    pool: Pool,
    rng: ChaCha8Rng,
}

impl VecEnv {
    /// `num_envs` envs (≥ 1) of `task`; env `i` is created with seed `seed + i`; steps use
    /// `num_threads` threads (clamped to 1..=num_envs): the caller plus `num_threads − 1`
    /// persistent worker threads owned by the VecEnv (1 = no extra threads).
    pub fn new(task: Task, num_envs: usize, seed: u64, num_threads: usize) -> Result<VecEnv, SimError> {
        if num_envs == 0 {
            return Err(SimError::InvalidArgument("num_envs must be at least 1".into()));
        }
        let envs = (0..num_envs).map(|i| Env::new(task, seed.wrapping_add(i as u64))).collect();
        let num_threads = num_threads.clamp(1, num_envs);
        Ok(VecEnv {
            task,
            envs,
            num_threads,
            pool: Pool::new(num_threads - 1),
            rng: ChaCha8Rng::seed_from_u64(seed ^ 0x5EED_0F5E_ED00),
        })
    }

    pub fn task(&self) -> Task {
        self.task
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

    /// Reset every env. `Some(s)`: env `i` gets episode seed `s + i`. `None`: each env draws its
    /// next seed from its own RNG. Writes `num_envs × obs_dim` floats.
    pub fn reset(&mut self, seed: Option<u64>, obs_out: &mut [f32]) -> Result<(), SimError> {
        let od = self.task.obs_dim();
        check("obs", self.envs.len() * od, obs_out.len())?;
        for (i, (env, o)) in self.envs.iter_mut().zip(obs_out.chunks_mut(od)).enumerate() {
            env.reset(seed.map(|s| s.wrapping_add(i as u64)), o)?;
        }
        Ok(())
    }

    /// Reset the envs whose mask entry is true (seeds from their own RNGs); the rows of the
    /// others in `obs_out` are filled with their current observation.
    pub fn reset_mask(&mut self, mask: &[bool], obs_out: &mut [f32]) -> Result<(), SimError> {
        let od = self.task.obs_dim();
        check("mask", self.envs.len(), mask.len())?;
        check("obs", self.envs.len() * od, obs_out.len())?;
        for ((env, o), &m) in self.envs.iter_mut().zip(obs_out.chunks_mut(od)).zip(mask) {
            if m {
                env.reset(None, o)?;
            } else {
                o.copy_from_slice(env.observation());
            }
        }
        Ok(())
    }

    /// Reset env `i` to episode `seed` and replay `actions` in it ([`Env::reset_replay`]); the
    /// other envs do not move. Writes env `i`'s observation (`obs_dim` floats) into `obs_out`.
    pub fn reset_replay(
        &mut self,
        i: usize,
        seed: u64,
        actions: &[f32],
        obs_out: &mut [f32],
    ) -> Result<usize, SimError> {
        let n = self.envs.len();
        let env = self
            .envs
            .get_mut(i)
            .ok_or_else(|| SimError::InvalidArgument(format!("env index {i} out of range (num_envs {n})")))?;
        env.reset_replay(seed, actions, obs_out)
    }

    /// Draw a fresh base seed from the VecEnv's own RNG (for callers that want `reset(Some(..))`
    /// without choosing a seed).
    pub fn next_seed(&mut self) -> u64 {
        self.rng.next_u64()
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
        let parts = self
            .envs
            .chunks_mut(chunk)
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
            .map(|((((((((((e, a), o), fo), r), te), tr), hf), pk), ins), fl)| Part {
                envs: e,
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
    envs: &'a mut [Env],
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
                // Infallible: the row has the right length.
                let _ = env.reset(None, row);
            } else {
                self.has_final[i] = false;
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
