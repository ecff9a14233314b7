"""One training update of BC + GAIL + PPO, the way Unity ML-Agents combines them, in CleanRL's
order. :meth:`Trainer.iterate` reads top to bottom:

1. **rollout** (:meth:`~Trainer.collect`): ``buffer_size`` steps from ``num_envs`` vectorised envs
   (``buffer_size / num_envs`` each), the stochastic policy acting; episode statistics on the way.
2. **reward signals** (:meth:`~Trainer.reward_signals`): the observation normalisers take the new
   observations first; then each signal on the buffer, scaled by its strength: extrinsic (the env's
   reward) and GAIL (-log(1 - D)), each with its own gamma and termination mask.
3. **GAE** (:meth:`~Trainer.advantages`): per signal, with that signal's value head; the advantage
   is the mean over signals, z-normalised; each head regresses its own returns.
4. **PPO** (:meth:`~Trainer.update`): ``num_epoch`` epochs of minibatches of ``batch_size``;
5. **GAIL**: one discriminator step per PPO minibatch, against an expert minibatch of the same
   size (ML-Agents' schedule, and the same random stream as before this layout). The steps read
   only the rollout and the demos, never the policy, so with ``torch_settings.overlap_gail`` they
   run on a second thread beside PPO and BC: each epoch's draws are taken on the main thread in
   the order one step after each PPO step takes them, which keeps every number bit for bit;
6. **BC**: one round over the demos (while its learning rate is above 1e-10);
7. **log**: the scalars gathered on the way, averaged per summary (:meth:`~Trainer.summary`).

Departures from ML-Agents (and why):
- Trajectories are the rollout's per-env segments of ``buffer_size / num_envs`` steps, cut at
  episode ends and every ``time_horizon`` steps, bootstrapped at every cut that is not a
  termination (truncations bootstrap from ``final_obs``). ML-Agents cuts per agent at
  ``time_horizon`` the same way; only the segment boundaries differ.
- Values used for GAE are recomputed in batch after the rollout, with the normaliser just updated
  (ML-Agents does the same in ``_process_trajectory``); no per-step critic call during rollout.
- ``--resume`` is exact (bit for bit: weights, optimisers, scalars) and checkpoints do not change
  training: the envs are reset once, at the start, with a seed derived from the run's seed, and a
  checkpoint (always at an update boundary) stores the vector env's ``state()``: its base seed,
  each env's episode count (the simulator derives every auto-reset's seed from (base, env index,
  episode count)) and the actions of each running episode. Resuming replays those actions (the
  simulator is deterministic) and checks that the replay reproduces the stored observations; the
  per-env running returns and the scalars not yet summarised are stored with it. Episodes run
  across checkpoints as if there were none.
- Env action = clip(u, -1, 1) instead of ML-Agents' clamp(u, -3, 3)/3 (see ``networks.py``).
- GAIL's survivor bias is handled with ``survivor_bias: bootstrap`` (see ``gail.py``).

The run around it (run dir, resume, checkpoints, the scalar log) is ``loop.py``.
"""

from __future__ import annotations

import math
import random
import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mimicrete._native import MimicreteError

from . import checkpoint, run_files
from . import config as config_mod
from .bc import BehavioralCloning
from .buffer import Rollout, Signal, UpdateBuffer, gae, horizon_cuts
from .curriculum import ReverseCurriculum, demo_tracks
from .demo_data import drop_idle_steps, read_demos
from .env import N_CONT, command_branches, final_obs_of, make_env, sim_task_of
from .episodes import Episode, EpisodeStats, EpisodeTracker
from .gail import Gail, signal_terminated
from .networks import Actor, Critic, env_action
from .ppo import (
    PPOBatch,
    PPOLossInfo,
    PPOStats,
    combine_advantages,
    explained_variance,
    ppo_loss,
    scheduled,
)

SIGNAL_TAG = {"extrinsic": "Extrinsic", "gail": "GAIL"}  # Policy/<tag> Reward, Value Estimate, ...


class NonFiniteLossError(MimicreteError, RuntimeError):
    """A loss or weight became NaN / infinite; the run stops before writing anything from it."""


class Trainer:
    """Networks, optimisers, reward signals, BC and the rollout of one training run."""

    def __init__(
        self,
        cfg: config_mod.TrainerConfig,
        run_dir: Path,
        demos_override: str | None,
        max_steps: int,
        *,
        skip_bad_demos: bool = False,
    ):
        self.cfg = cfg
        self.b = cfg.behavior
        self.h = self.b.hyperparameters
        self.run_dir = Path(run_dir)
        self.max_steps = max_steps
        self.seed = cfg.env_settings.seed
        torch.set_num_threads(max(1, cfg.torch_settings.num_threads))
        random.seed(self.seed)
        np.random.seed(self.seed % 2**32)
        torch.manual_seed(self.seed)
        self.rng = np.random.default_rng(self.seed)

        self.N = cfg.env_settings.num_envs
        self.T = self.h.buffer_size // self.N
        self.env = make_env(cfg.env_settings.env_id, self.N, self.seed)
        self.obs_dim = int(self.env.single_observation_space.shape[0])
        self.n_branches = command_branches(self.env)  # 1 (end effector), Screw 2 (+ spin)

        rs = self.b.reward_signals
        self.signals: list[str] = [
            name for name, s in (("extrinsic", rs.extrinsic), ("gail", rs.gail)) if s is not None
        ]
        ns = self.b.network_settings
        self.actor = Actor(
            self.obs_dim,
            N_CONT,
            ns.hidden_units,
            ns.num_layers,
            ns.normalize,
            self.n_branches,
            self.b.init_std,
        )
        self.critic = Critic(
            self.obs_dim, len(self.signals), ns.hidden_units, ns.num_layers, ns.normalize
        )
        self.opt = torch.optim.Adam(
            list(self.actor.parameters()) + list(self.critic.parameters()), lr=self.h.learning_rate
        )

        self.demos: dict[str, np.ndarray] | None = None
        self.demo_steps_loaded = 0
        self.demo_files_skipped: list[str] = []
        if rs.gail is not None or self.b.behavioral_cloning is not None:
            path = demos_override or cfg.demo_path
            if not path:
                raise config_mod.ConfigError("gail/behavioral_cloning need a demo_path or --demos")
            loaded = read_demos(path, self.b.demo_episodes, skip_bad=skip_bad_demos)
            self.demo_files_skipped = loaded.skipped
            self.demo_steps_loaded = len(loaded.arrays["actions"])
            self.demos = drop_idle_steps(loaded.arrays, self.b.demo_drop_idle)
            act_dim = self.demos["actions"].shape[1]
            if act_dim != N_CONT + self.n_branches:
                raise config_mod.ConfigError(
                    f"{path}: demo actions of {act_dim} dims, {cfg.env_settings.env_id} takes "
                    f"{N_CONT + self.n_branches} (demos of another task?)"
                )
            sim = sim_task_of(cfg.env_settings.env_id)
            if sim is not None:  # the sizes can match across tasks (grip and suction do)
                loaded.check_task(sim, path)
        self.gail: Gail | None = None
        if rs.gail is not None:
            assert self.demos is not None
            g = rs.gail
            self.gail = Gail(
                self._disc_inputs(self.demos["obs"], self.demos["actions"]),
                g.network_settings.hidden_units,
                g.network_settings.num_layers,
                g.learning_rate,
                normalize=g.network_settings.normalize,
            )
        # GAIL's discriminator steps on a thread of their own (see step 5 above); the thread
        # gets the same torch thread count (OpenMP's is per thread)
        self._gail_pool: ThreadPoolExecutor | None = None
        if self.gail is not None and cfg.torch_settings.overlap_gail:
            self._gail_pool = ThreadPoolExecutor(
                1,
                thread_name_prefix="gail",
                initializer=torch.set_num_threads,
                initargs=(max(1, cfg.torch_settings.num_threads),),
            )
        self.bc: BehavioralCloning | None = None
        bcs = self.b.behavioral_cloning
        if bcs is not None:
            assert self.demos is not None
            self.bc = BehavioralCloning(
                self.actor,
                self.demos["obs"],
                self.demos["actions"],
                initial_lr=self.h.learning_rate * bcs.strength,
                steps=bcs.steps,
                batch_size=bcs.batch_size or self.h.batch_size,
                num_epoch=bcs.num_epoch or self.h.num_epoch,
                samples_per_update=bcs.samples_per_update,
                ee_class_balance=bcs.ee_class_balance,
            )

        self.curriculum: ReverseCurriculum | None = None
        if self.b.demo_curriculum is not None:
            path = demos_override or cfg.demo_path
            if not path:
                raise config_mod.ConfigError("demo_curriculum needs a demo_path or --demos")
            if not hasattr(self.env, "reset_replay"):
                raise config_mod.ConfigError(
                    f"demo_curriculum: {cfg.env_settings.env_id} cannot replay demos"
                )
            tracks = demo_tracks(path, self.b.demo_episodes)
            self.curriculum = ReverseCurriculum(
                tracks[: self.b.demo_curriculum.max_demos],
                self.b.demo_curriculum,
                self.N,
                np.random.default_rng(self.seed + 1),
            )

        self.step = 0
        self.update_idx = 0
        self.converged_streak = 0  # summaries in a row that met stop_on_convergence
        self.last_summary_step = 0
        self.rollout = Rollout(self.T, self.N, self.obs_dim, N_CONT, self.n_branches)
        self.obs: np.ndarray | None = None
        self.episodes = EpisodeTracker(self.N)
        self._window: list[Episode] = []  # episodes finished since the last summary
        self._sig_window: dict[str, list[float]] = {s: [] for s in self.signals}
        self._sig_acc = {s: np.zeros(self.N) for s in self.signals}
        self._update_stats: dict[str, list[float]] = {}
        self.recent_installed = 0.0
        self.recent_picked = 0.0
        self._t_summary = time.perf_counter()
        self._t_start = self._t_summary  # Environment/Elapsed Seconds counts from here
        self._steps_at_t = 0

    def pretrain(self) -> dict[str, float] | None:
        """Offline BC warm start (``behavioral_cloning.pretrain_steps`` or ``pretrain_passes``,
        a mimicrete extension); returns its size (gradient steps, passes over the demo steps,
        demo steps) for ``run.json``, or None without one. The observation normalisers are first
        seeded with the demos' statistics so that the warm-started policy sees the same inputs
        once agent data starts flowing in."""
        bcs = self.b.behavioral_cloning
        if self.bc is None or bcs is None:
            return None
        per_pass = self.bc.batches_per_pass()
        steps = bcs.pretrain_steps or round(bcs.pretrain_passes * per_pass)
        if steps <= 0:
            return None
        demo_obs = torch.from_numpy(np.asarray(self.bc.obs))
        self.actor.norm.update(demo_obs)
        self.critic.norm.update(demo_obs)
        losses = self.bc.pretrain(steps, self.rng)
        self._check_finite("BC warm-start", losses[-1] if losses else 0.0)
        self._log("Losses/Pretraining Loss", float(np.mean(losses[-50:])))
        return {
            "grad_steps": steps,
            "passes": round(steps / per_pass, 2),
            "demo_steps": int(self.bc.obs.shape[0]),
        }

    def iterate(self) -> None:
        """One update: rollout -> reward signals -> GAE -> PPO (+ GAIL) -> BC."""
        self.collect()
        buf = self.advantages(self.reward_signals())
        self.update(buf)

    # -- 1. rollout -------------------------------------------------------------------------------

    def collect(self) -> None:
        """``T`` steps of every env into :attr:`rollout`; finished episodes into the window."""
        ro = self.rollout
        if self.obs is None:
            self._reset_envs()
        obs = self.obs
        assert obs is not None
        for t in range(self.T):
            u, k, logp = self.actor.sample(torch.from_numpy(obs))
            act = env_action(u, k).numpy()
            ro.obs[t] = obs
            ro.u[t] = u.numpy()
            ro.k[t] = k.numpy()
            ro.logp[t] = logp.numpy()
            ro.env_actions[t] = act
            nobs, r, term, trunc, infos = self.env.step(act)
            r = np.asarray(r, np.float32)
            term = np.asarray(term, bool)
            trunc = np.asarray(trunc, bool)
            nobs = np.array(nobs, np.float32)
            env_ended = term | trunc
            cut = np.zeros_like(env_ended)
            if self.curriculum is not None:  # demo-start episodes past their horizon
                cut = self.curriculum.over_horizon(env_ended)
                trunc = trunc | cut
            ro.rewards[t] = r
            ro.terminated[t] = term
            ro.truncated[t] = trunc
            finished = self.episodes.step(infos, r, term, trunc)
            if env_ended.any():
                ro.final_obs[t, env_ended] = final_obs_of(infos, env_ended)
            if cut.any():
                ro.final_obs[t, cut] = nobs[cut]  # not reset by the env: nobs is its last obs
            for i, ep in finished:
                d = -1 if self.curriculum is None else int(self.curriculum.env_demo[i])
                if d < 0:
                    self._window.append(ep)
                    if self.curriculum is not None:
                        self.curriculum.record_own(i, ep.installed)
                else:
                    assert self.curriculum is not None
                    self.curriculum.record(d, ep.installed, bool(self.curriculum.env_frontier[i]))
            if self.curriculum is not None and (env_ended | cut).any():
                self.curriculum.restart(self.env, env_ended | cut, cut, nobs)
            obs = nobs
        ro.last_obs[:] = obs
        self.obs = obs
        self.step += self.T * self.N

    def _reset_envs(self) -> None:
        """Reset every env with a seed derived from (seed, update index) (at the run's start;
        a checkpoint of an older version resumes here too)."""
        s = (self.seed * 1_000_003 + self.update_idx * 7919) % 2**31
        self.obs, _ = self.env.reset(seed=s)
        self.obs = np.asarray(self.obs, np.float32)
        self.episodes.reset()
        self._sig_acc = {k: np.zeros(self.N) for k in self.signals}
        if self.curriculum is not None:  # some envs start inside a demo right away
            self.curriculum.forget_envs()
            every = np.ones(self.N, bool)
            self.curriculum.restart(self.env, every, ~every, self.obs)

    # -- 2. reward signals ------------------------------------------------------------------------

    def reward_signals(self) -> list[Signal]:
        """Update the observation normalisers with the rollout, then every reward signal on it
        (strength-scaled); per-episode sums go to ``Policy/<Signal> Reward``."""
        ro = self.rollout
        T, N, D = self.T, self.N, self.obs_dim
        obs_flat = torch.from_numpy(ro.obs.reshape(T * N, D))
        self.actor.norm.update(obs_flat)
        self.critic.norm.update(obs_flat)
        rs = self.b.reward_signals
        out = []
        for name in self.signals:
            if name == "extrinsic":
                assert rs.extrinsic is not None
                r = rs.extrinsic.strength * ro.rewards.astype(np.float64)
                sig = Signal(name, r, rs.extrinsic.gamma, ro.terminated)
            else:
                assert rs.gail is not None and self.gail is not None
                x = self._disc_inputs(ro.obs.reshape(T * N, D), ro.env_actions.reshape(T * N, -1))
                r = rs.gail.strength * self.gail.rewards(torch.from_numpy(x)).reshape(T, N)
                term = signal_terminated(ro.terminated, rs.gail.survivor_bias)
                sig = Signal(name, r.astype(np.float64), rs.gail.gamma, term)
            self._episode_signal_sums(sig)
            out.append(sig)
        return out

    def _episode_signal_sums(self, sig: Signal) -> None:
        """Per-episode sums of a (strength-scaled) signal, as ML-Agents' Policy/<Signal> Reward."""
        acc = self._sig_acc[sig.name]
        ended = self.rollout.ended
        for t in range(self.T):
            acc += sig.rewards[t]
            if ended[t].any():
                self._sig_window[sig.name].extend(acc[ended[t]].tolist())
                acc[ended[t]] = 0.0

    def _disc_inputs(self, obs: np.ndarray, actions: np.ndarray) -> np.ndarray:
        g = self.b.reward_signals.gail
        if g is not None and g.use_actions:
            return np.concatenate([obs, actions], -1).astype(np.float32)
        return np.asarray(obs, np.float32)

    # -- 3. GAE -----------------------------------------------------------------------------------

    def advantages(self, signals: list[Signal]) -> UpdateBuffer:
        """Per-signal GAE with the signal's gamma and value head (cuts: episode ends, every
        ``time_horizon`` steps, the rollout's end); the combined advantage; the flat buffer."""
        ro = self.rollout
        T, N, D = self.T, self.N, self.obs_dim
        with torch.no_grad():
            v32, nv32 = ro.values_and_next(lambda x: self.critic(torch.from_numpy(x)).numpy())
        values, next_values = v32.astype(np.float64), nv32.astype(np.float64)
        cut = ro.ended | horizon_cuts(T, N, self.b.time_horizon)
        advs, rets = [], []
        for i, sig in enumerate(signals):
            v = values[..., i]
            a, ret = gae(sig.rewards, v, next_values[..., i], sig.terminated, cut, sig.gamma,
                         self.h.lambd)  # fmt: skip
            tag = SIGNAL_TAG[sig.name]
            self._log(f"Policy/{tag} Value Estimate", v.mean())
            self._log(f"Policy/{tag} Explained Variance", explained_variance(v, ret))
            advs.append(a)
            rets.append(ret)
        adv = combine_advantages(advs)
        return UpdateBuffer(
            obs=ro.obs.reshape(T * N, D),
            u=ro.u.reshape(T * N, N_CONT),
            k=ro.k.reshape(T * N, -1),
            logp=ro.logp.reshape(T * N, -1),
            env_actions=ro.env_actions.reshape(T * N, -1),
            adv=adv.reshape(T * N).astype(np.float32),
            values=values.reshape(T * N, -1).astype(np.float32),
            returns=np.stack(rets, -1).reshape(T * N, -1).astype(np.float32),
        )

    def process(self) -> UpdateBuffer:
        """Steps 2 and 3 (reward signals, GAE) on the collected rollout."""
        return self.advantages(self.reward_signals())

    # -- 4.-6. PPO, GAIL, BC ----------------------------------------------------------------------

    def update(self, buf: UpdateBuffer) -> None:
        """PPO epochs over minibatches, each followed by one GAIL discriminator step; then one
        BC round. Schedules (lr, epsilon, beta) follow the env step."""
        h = self.h
        lr = scheduled(
            h.learning_rate_schedule, "linear", h.learning_rate, 1e-10, self.step, self.max_steps
        )
        eps = scheduled(
            h.epsilon_schedule, h.learning_rate_schedule, h.epsilon, 0.1, self.step, self.max_steps
        )
        beta = scheduled(
            h.beta_schedule, h.learning_rate_schedule, h.beta, 1e-5, self.step, self.max_steps
        )
        for g in self.opt.param_groups:
            g["lr"] = lr
        self._log("Policy/Learning Rate", lr)
        self._log("Policy/Epsilon", eps)
        self._log("Policy/Beta", beta)
        t = buf.tensors()
        n, bs = len(buf.adv), h.batch_size
        stats = PPOStats()
        gail_epochs: list[Future] = []
        for _ in range(h.num_epoch):
            perm = torch.as_tensor(self.rng.permutation(n))
            batches = [perm[s : s + bs] for s in range(0, n - bs + 1, bs)]
            if self.gail is not None:
                # the draws one GAIL step after each PPO step would take, in that order
                draws = [self.gail.draw(bs, self.rng) for _ in batches]
                gail_epochs.append(self._submit_gail(buf, batches, draws))
            for idx in batches:
                stats.add(self._ppo_step(t, idx, eps, beta))
        m = stats.mean()
        self._log("Losses/Policy Loss", abs(m["policy_loss"]))
        self._log("Losses/Value Loss", m["value_loss"])
        self._log("Policy/Entropy", m["entropy"])
        self._log("Policy/Approx KL", m["approx_kl"])
        self._log("Policy/Clip Fraction", m["clipfrac"])
        self._bc_round()
        for job in gail_epochs:
            for gs in job.result():
                self._check_finite("GAIL", gs["loss"])
                self._log("Losses/GAIL Loss", gs["loss"])
                self._log("Policy/GAIL Grad Mag Loss", gs["grad_penalty"])
                self._log("Policy/GAIL Expert Estimate", gs["expert_estimate"])
                self._log("Policy/GAIL Policy Estimate", gs["policy_estimate"])
        self.update_idx += 1

    def _ppo_step(
        self, t: dict[str, torch.Tensor], idx: torch.Tensor, eps: float, beta: float
    ) -> PPOLossInfo:
        batch = PPOBatch(
            obs=t["obs"][idx],
            u=t["u"][idx],
            k=t["k"][idx],
            old_logp=t["logp"][idx],
            adv=t["adv"][idx],
            old_values=t["values"][idx],
            returns=t["returns"][idx],
        )
        loss, info = ppo_loss(self.actor, self.critic, batch, eps, beta)
        self._check_finite("PPO", loss.item())
        self.opt.zero_grad()
        loss.backward()
        self.opt.step()
        return info

    def close(self) -> None:
        """Release the envs and the GAIL thread once training is over (the trainer's weights,
        normalisers and state stay readable)."""
        self.env.close()
        if self._gail_pool is not None:
            self._gail_pool.shutdown(wait=True)
            self._gail_pool = None

    def _submit_gail(self, buf: UpdateBuffer, batches: list, draws: list) -> Future:
        """One epoch's discriminator steps: on the GAIL thread, or here and now."""
        if self._gail_pool is not None:
            return self._gail_pool.submit(self._gail_steps, buf, batches, draws)
        done: Future = Future()
        done.set_result(self._gail_steps(buf, batches, draws))
        return done

    def _gail_steps(self, buf: UpdateBuffer, batches: list, draws: list) -> list[dict]:
        """Discriminator steps on the rollout's minibatches ``batches`` (touches no generator)."""
        assert self.gail is not None
        out = []
        for idx, draw in zip(batches, draws, strict=True):
            i = idx.numpy()
            x = self._disc_inputs(buf.obs[i], buf.env_actions[i])
            out.append(self.gail.step(torch.from_numpy(x), draw))
        return out

    def _bc_round(self) -> None:
        if self.bc is None:
            return
        res = self.bc.update(self.step, self.rng)
        if res is not None:
            self._check_finite("BC", res[0])
            self._log("Losses/Pretraining Loss", res[0])
            self._log("Losses/Pretraining Learning Rate", res[1])

    def _check_finite(self, what: str, loss: float) -> None:
        if not math.isfinite(loss):
            raise NonFiniteLossError(self._nonfinite_message(f"the {what} loss is {loss}"))

    def _nonfinite_message(self, what: str) -> str:
        ck = run_files.latest_checkpoint(self.run_dir)
        kept = f"the last good checkpoint is {ck}" if ck else "no checkpoint was written yet"
        return (
            f"{what} at step {self.step} (update {self.update_idx}); training stopped, {kept} "
            "(a smaller learning rate or strength may help)"
        )

    # -- 7. log -----------------------------------------------------------------------------------

    def _log(self, key: str, value: float) -> None:
        self._update_stats.setdefault(key, []).append(float(value))

    def summary(self) -> dict[str, float] | None:
        """Scalars since the last summary (None if nothing to report)."""
        row: dict[str, float] = {}
        if self._window:
            st = EpisodeStats.of(self._window)
            row["Environment/Cumulative Reward"] = st.mean_return
            row["Environment/Episode Length"] = st.mean_length
            row["Environment/Picked Rate"] = st.picked_rate
            row["Environment/Installed Rate"] = st.installed_rate
            row["Environment/Episodes"] = float(st.episodes)
            self.recent_installed = st.installed_rate
            self.recent_picked = st.picked_rate
        for name in self.signals:
            if self._sig_window.get(name):
                row[f"Policy/{SIGNAL_TAG[name]} Reward"] = float(np.mean(self._sig_window[name]))
        for k, v in self._update_stats.items():
            row[k] = float(np.mean(v))
        if self.curriculum is not None:
            row.update(self.curriculum.summary())
        now = time.perf_counter()
        row["Environment/Steps Per Second"] = (self.step - self._steps_at_t) / max(
            now - self._t_summary, 1e-9
        )
        row["Environment/Elapsed Seconds"] = now - self._t_start
        self._t_summary, self._steps_at_t = now, self.step
        self._window.clear()
        for v in self._sig_window.values():
            v.clear()
        self._update_stats.clear()
        return row

    # -- checkpoints ------------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """Everything an exact resume needs (``checkpoint.py``)."""
        return checkpoint.trainer_state(self)

    def load_state_dict(self, s: dict[str, Any]) -> None:
        checkpoint.load_trainer_state(self, s)

    def save_checkpoint(self) -> Path:
        """``checkpoints/step_<step>.pt``; refuses (:class:`NonFiniteLossError`) when a weight
        is not finite, so the last checkpoint on disk is always a good one."""
        nets = [self.actor, self.critic] + ([self.gail.disc] if self.gail is not None else [])
        for net in nets:
            for name, p in net.named_parameters():
                if not torch.isfinite(p).all():
                    raise NonFiniteLossError(
                        self._nonfinite_message(f"weight {name} is not finite")
                    )
        path = run_files.save_checkpoint(
            self.run_dir, self.step, self.state_dict(), self.b.keep_checkpoints
        )
        return path
