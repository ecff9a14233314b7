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

What the update changes (networks, optimisers, envs, buffers, counters, the run's random stream,
the scalars not yet summarised) is one :class:`~run_state.RunState`, :attr:`Trainer.state`;
``checkpoint.py`` saves and restores exactly that. The run around it (run dir, resume,
checkpoints, the scalar log) is ``loop.py``.
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
from .buffer import Signal, UpdateBuffer, gae, horizon_cuts
from .demo_data import TrainingDemos, read_training_demos
from .env import N_CONT, command_branches, final_obs_of, make_env
from .episodes import EpisodeStats
from .gail import signal_terminated
from .networks import env_action
from .ppo import (
    PPOBatch,
    PPOLossInfo,
    PPOStats,
    combine_advantages,
    explained_variance,
    ppo_loss,
    scheduled,
)
from .run_state import RunState, disc_inputs, new_run_state

SIGNAL_TAG = {"extrinsic": "Extrinsic", "gail": "GAIL"}  # Policy/<tag> Reward, Value Estimate, ...


class NonFiniteLossError(MimicreteError, RuntimeError):
    """A loss or weight became NaN / infinite; the run stops before writing anything from it."""


class Trainer:
    """One training run's update: its fixed setup (config, demos, sizes) and its
    :class:`~run_state.RunState` (:attr:`state`), which every update changes."""

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
        self.behavior = cfg.behavior
        self.hp = cfg.behavior.hyperparameters
        self.run_dir = Path(run_dir)
        self.max_steps = max_steps
        self.seed = cfg.env_settings.seed
        threads = max(1, cfg.torch_settings.num_threads)
        torch.set_num_threads(threads)
        random.seed(self.seed)
        np.random.seed(self.seed % 2**32)
        torch.manual_seed(self.seed)

        self.N = cfg.env_settings.num_envs
        self.T = self.hp.buffer_size // self.N  # steps per env per rollout
        env = make_env(cfg.env_settings.env_id, self.N, self.seed)
        self.obs_dim = int(env.single_observation_space.shape[0])
        self.n_branches = command_branches(env)  # 1 (end effector), Screw 2 (+ spin)
        b = self.behavior
        self.demos: TrainingDemos | None = None
        wants_demos = (b.reward_signals.gail, b.behavioral_cloning, b.demo_curriculum)
        if any(x is not None for x in wants_demos):  # read once, for all three
            self.demos = read_training_demos(
                demos_override or cfg.demo_path, b.demo_episodes, b.demo_drop_idle,
                cfg.env_settings.env_id, N_CONT + self.n_branches, skip_bad=skip_bad_demos,
            )  # fmt: skip
        self.state: RunState = new_run_state(
            cfg, env, self.obs_dim, self.n_branches, self.demos, self.seed
        )
        # GAIL's discriminator steps on a thread of their own (step 5 above); the thread gets
        # the same torch thread count (OpenMP's is per thread)
        self._gail_pool: ThreadPoolExecutor | None = None
        if self.state.gail is not None and cfg.torch_settings.overlap_gail:
            self._gail_pool = ThreadPoolExecutor(
                1, thread_name_prefix="gail", initializer=torch.set_num_threads,
                initargs=(threads,),
            )  # fmt: skip
        self._t_summary = time.perf_counter()
        self._t_start = self._t_summary  # Environment/Elapsed Seconds counts from here
        self._steps_at_t = 0

    @property
    def step(self) -> int:
        """Env steps trained so far (``state.step``)."""
        return self.state.step

    @property
    def demo_steps_loaded(self) -> int:
        return self.demos.steps_loaded if self.demos is not None else 0

    @property
    def demo_files_skipped(self) -> list[str]:
        return self.demos.skipped if self.demos is not None else []

    def pretrain(self) -> dict[str, float] | None:
        """Offline BC warm start (``behavioral_cloning.pretrain_steps`` or ``pretrain_passes``,
        a mimicrete extension); returns its size (gradient steps, passes over the demo steps,
        demo steps) for ``run.json``, or None without one. The observation normalisers are first
        seeded with the demos' statistics so that the warm-started policy sees the same inputs
        once agent data starts flowing in."""
        st, bcs = self.state, self.behavior.behavioral_cloning
        if st.bc is None or bcs is None:
            return None
        per_pass = st.bc.batches_per_pass()
        steps = bcs.pretrain_steps or round(bcs.pretrain_passes * per_pass)
        if steps <= 0:
            return None
        demo_obs = torch.from_numpy(np.asarray(st.bc.obs))
        st.actor.norm.update(demo_obs)
        st.critic.norm.update(demo_obs)
        losses = st.bc.pretrain(steps, st.rng)
        self._check_finite("BC warm-start", losses[-1] if losses else 0.0)
        st.pending.log("Losses/Pretraining Loss", float(np.mean(losses[-50:])))
        return {
            "grad_steps": steps,
            "passes": round(steps / per_pass, 2),
            "demo_steps": int(st.bc.obs.shape[0]),
        }

    def iterate(self) -> None:
        """One update: rollout -> reward signals -> GAE -> PPO (+ GAIL) -> BC."""
        self.collect()  # 1.
        signals = self.reward_signals()  # 2.
        buf = self.advantages(signals)  # 3.
        self.update(buf)  # 4.-6.

    # -- 1. rollout -------------------------------------------------------------------------------

    def collect(self) -> None:
        """``T`` steps of every env into ``state.rollout``; finished episodes into the
        pending summary."""
        st = self.state
        ro, cur = st.rollout, st.curriculum
        if st.obs is None:
            self._reset_envs()
        obs = st.obs
        assert obs is not None
        for t in range(self.T):
            u, k, logp = st.actor.sample(torch.from_numpy(obs))
            act = env_action(u, k).numpy()
            ro.obs[t] = obs
            ro.u[t] = u.numpy()
            ro.k[t] = k.numpy()
            ro.logp[t] = logp.numpy()
            ro.env_actions[t] = act
            nobs, r, term, trunc, infos = st.env.step(act)
            r = np.asarray(r, np.float32)
            term = np.asarray(term, bool)
            trunc = np.asarray(trunc, bool)
            nobs = np.array(nobs, np.float32)
            env_ended = term | trunc
            cut = np.zeros_like(env_ended)
            if cur is not None:  # demo-start episodes past their horizon
                cut = cur.over_horizon(env_ended)
                trunc = trunc | cut
            ro.rewards[t] = r
            ro.terminated[t] = term
            ro.truncated[t] = trunc
            finished = st.episodes.step(infos, r, term, trunc)
            if env_ended.any():
                ro.final_obs[t, env_ended] = final_obs_of(infos, env_ended)
            if cut.any():
                ro.final_obs[t, cut] = nobs[cut]  # not reset by the env: nobs is its last obs
            for i, ep in finished:
                d = -1 if cur is None else int(cur.env_demo[i])
                if d < 0:
                    st.pending.episodes.append(ep)
                    if cur is not None:
                        cur.record_own(i, ep.installed)
                else:
                    assert cur is not None
                    cur.record(d, ep.installed, bool(cur.env_frontier[i]))
            if cur is not None and (env_ended | cut).any():
                cur.restart(st.env, env_ended | cut, cut, nobs)
            obs = nobs
        ro.last_obs[:] = obs
        st.obs = obs
        st.step += self.T * self.N

    def _reset_envs(self) -> None:
        """Reset every env with a seed derived from (seed, update index) (at the run's start;
        a checkpoint of an older version resumes here too)."""
        st = self.state
        s = (self.seed * 1_000_003 + st.update_idx * 7919) % 2**31
        obs, _ = st.env.reset(seed=s)
        st.obs = np.asarray(obs, np.float32)
        st.episodes.reset()
        st.reset_signal_sums()
        if st.curriculum is not None:  # some envs start inside a demo right away
            st.curriculum.forget_envs()
            every = np.ones(self.N, bool)
            st.curriculum.restart(st.env, every, ~every, st.obs)

    # -- 2. reward signals ------------------------------------------------------------------------

    def reward_signals(self) -> list[Signal]:
        """Update the observation normalisers with the rollout, then every reward signal on it
        (strength-scaled); per-episode sums go to ``Policy/<Signal> Reward``."""
        st = self.state
        ro = st.rollout
        T, N, D = self.T, self.N, self.obs_dim
        obs_flat = torch.from_numpy(ro.obs.reshape(T * N, D))
        st.actor.norm.update(obs_flat)
        st.critic.norm.update(obs_flat)
        rs = self.behavior.reward_signals
        out = []
        for name in st.signals:
            if name == "extrinsic":
                assert rs.extrinsic is not None
                r = rs.extrinsic.strength * ro.rewards.astype(np.float64)
                sig = Signal(name, r, rs.extrinsic.gamma, ro.terminated)
            else:
                assert rs.gail is not None and st.gail is not None
                acts = ro.env_actions.reshape(T * N, -1)
                x = disc_inputs(rs.gail, ro.obs.reshape(T * N, D), acts)
                r = rs.gail.strength * st.gail.rewards(torch.from_numpy(x)).reshape(T, N)
                term = signal_terminated(ro.terminated, rs.gail.survivor_bias)
                sig = Signal(name, r.astype(np.float64), rs.gail.gamma, term)
            self._episode_signal_sums(sig)
            out.append(sig)
        return out

    def _episode_signal_sums(self, sig: Signal) -> None:
        """Per-episode sums of a (strength-scaled) signal, as ML-Agents' Policy/<Signal> Reward."""
        st = self.state
        acc = st.signal_sums[sig.name]
        ended = st.rollout.ended
        for t in range(self.T):
            acc += sig.rewards[t]
            if ended[t].any():
                st.pending.signal_returns[sig.name].extend(acc[ended[t]].tolist())
                acc[ended[t]] = 0.0

    # -- 3. GAE -----------------------------------------------------------------------------------

    def advantages(self, signals: list[Signal]) -> UpdateBuffer:
        """Per-signal GAE with the signal's gamma and value head (cuts: episode ends, every
        ``time_horizon`` steps, the rollout's end); the combined advantage; the flat buffer."""
        st = self.state
        ro = st.rollout
        T, N, D = self.T, self.N, self.obs_dim
        with torch.no_grad():
            v32, nv32 = ro.values_and_next(lambda x: st.critic(torch.from_numpy(x)).numpy())
        values, next_values = v32.astype(np.float64), nv32.astype(np.float64)
        cut = ro.ended | horizon_cuts(T, N, self.behavior.time_horizon)
        advs, rets = [], []
        for i, sig in enumerate(signals):
            v = values[..., i]
            a, ret = gae(sig.rewards, v, next_values[..., i], sig.terminated, cut, sig.gamma,
                         self.hp.lambd)  # fmt: skip
            tag = SIGNAL_TAG[sig.name]
            st.pending.log(f"Policy/{tag} Value Estimate", v.mean())
            st.pending.log(f"Policy/{tag} Explained Variance", explained_variance(v, ret))
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

    # -- 4.-6. PPO, GAIL, BC ----------------------------------------------------------------------

    def update(self, buf: UpdateBuffer) -> None:
        """PPO epochs over minibatches, each followed by one GAIL discriminator step; then one
        BC round. Schedules (lr, epsilon, beta) follow the env step."""
        st, hp, log = self.state, self.hp, self.state.pending.log
        # schedules: linear over max_steps unless constant
        at = (st.step, self.max_steps)
        lr = scheduled(hp.learning_rate_schedule, "linear", hp.learning_rate, 1e-10, *at)
        eps = scheduled(hp.epsilon_schedule, hp.learning_rate_schedule, hp.epsilon, 0.1, *at)
        beta = scheduled(hp.beta_schedule, hp.learning_rate_schedule, hp.beta, 1e-5, *at)
        for g in st.opt.param_groups:
            g["lr"] = lr
        log("Policy/Learning Rate", lr)
        log("Policy/Epsilon", eps)
        log("Policy/Beta", beta)

        # 4. PPO: num_epoch epochs over shuffled minibatches; 5. GAIL: one discriminator step per
        # minibatch, its draws taken here in the order the sequential steps would take them
        b_t = buf.tensors()
        n, bs = len(buf.adv), hp.batch_size
        stats = PPOStats()
        gail_epochs: list[Future] = []
        for _ in range(hp.num_epoch):
            perm = torch.as_tensor(st.rng.permutation(n))
            batches = [perm[s : s + bs] for s in range(0, n - bs + 1, bs)]
            if st.gail is not None:
                draws = [st.gail.draw(bs, st.rng) for _ in batches]
                gail_epochs.append(self._submit_gail(buf, batches, draws))
            for mb_inds in batches:
                stats.add(self._ppo_step(b_t, mb_inds, eps, beta))
        m = stats.mean()
        log("Losses/Policy Loss", abs(m["policy_loss"]))
        log("Losses/Value Loss", m["value_loss"])
        log("Policy/Entropy", m["entropy"])
        log("Policy/Approx KL", m["approx_kl"])
        log("Policy/Clip Fraction", m["clipfrac"])

        # 6. BC: one round over the demos
        self._bc_round()

        # 5. (collected) the discriminator steps' scalars
        for job in gail_epochs:
            for gs in job.result():
                self._check_finite("GAIL", gs["loss"])
                log("Losses/GAIL Loss", gs["loss"])
                log("Policy/GAIL Grad Mag Loss", gs["grad_penalty"])
                log("Policy/GAIL Expert Estimate", gs["expert_estimate"])
                log("Policy/GAIL Policy Estimate", gs["policy_estimate"])
        st.update_idx += 1

    def _ppo_step(
        self, b_t: dict[str, torch.Tensor], mb_inds: torch.Tensor, eps: float, beta: float
    ) -> PPOLossInfo:
        """One Adam step of PPO's loss on the minibatch ``mb_inds`` of the update buffer."""
        st = self.state
        batch = PPOBatch(
            obs=b_t["obs"][mb_inds],
            u=b_t["u"][mb_inds],
            k=b_t["k"][mb_inds],
            old_logp=b_t["logp"][mb_inds],
            adv=b_t["adv"][mb_inds],
            old_values=b_t["values"][mb_inds],
            returns=b_t["returns"][mb_inds],
        )
        loss, info = ppo_loss(st.actor, st.critic, batch, eps, beta)
        self._check_finite("PPO", loss.item())
        st.opt.zero_grad()
        loss.backward()
        st.opt.step()
        return info

    def _submit_gail(self, buf: UpdateBuffer, batches: list, draws: list) -> Future:
        """One epoch's discriminator steps: on the GAIL thread, or here and now."""
        if self._gail_pool is not None:
            return self._gail_pool.submit(self._gail_steps, buf, batches, draws)
        done: Future = Future()
        done.set_result(self._gail_steps(buf, batches, draws))
        return done

    def _gail_steps(self, buf: UpdateBuffer, batches: list, draws: list) -> list[dict]:
        """Discriminator steps on the rollout's minibatches ``batches`` (touches no generator)."""
        gail, g = self.state.gail, self.behavior.reward_signals.gail
        assert gail is not None
        out = []
        for mb_inds, draw in zip(batches, draws, strict=True):
            i = mb_inds.numpy()
            x = disc_inputs(g, buf.obs[i], buf.env_actions[i])
            out.append(gail.step(torch.from_numpy(x), draw))
        return out

    def _bc_round(self) -> None:
        st = self.state
        if st.bc is None:
            return
        res = st.bc.update(st.step, st.rng)
        if res is not None:
            self._check_finite("BC", res[0])
            st.pending.log("Losses/Pretraining Loss", res[0])
            st.pending.log("Losses/Pretraining Learning Rate", res[1])

    def close(self) -> None:
        """Release the envs and the GAIL thread once training is over (the trainer's weights,
        normalisers and state stay readable)."""
        self.state.env.close()
        if self._gail_pool is not None:
            self._gail_pool.shutdown(wait=True)
            self._gail_pool = None

    def _check_finite(self, what: str, loss: float) -> None:
        if not math.isfinite(loss):
            raise NonFiniteLossError(self._nonfinite_message(f"the {what} loss is {loss}"))

    def _nonfinite_message(self, what: str) -> str:
        ck = run_files.latest_checkpoint(self.run_dir)
        kept = f"the last good checkpoint is {ck}" if ck else "no checkpoint was written yet"
        return (
            f"{what} at step {self.state.step} (update {self.state.update_idx}); training "
            f"stopped, {kept} (a smaller learning rate or strength may help)"
        )

    # -- 7. log -----------------------------------------------------------------------------------

    def summary(self) -> dict[str, float] | None:
        """Scalars since the last summary (None if nothing to report)."""
        st, pending = self.state, self.state.pending
        row: dict[str, float] = {}
        if pending.episodes:
            es = EpisodeStats.of(pending.episodes)
            row["Environment/Cumulative Reward"] = es.mean_return
            row["Environment/Episode Length"] = es.mean_length
            row["Environment/Picked Rate"] = es.picked_rate
            row["Environment/Installed Rate"] = es.installed_rate
            row["Environment/Episodes"] = float(es.episodes)
            st.recent_installed = es.installed_rate
            st.recent_picked = es.picked_rate
        for name in st.signals:
            if pending.signal_returns.get(name):
                row[f"Policy/{SIGNAL_TAG[name]} Reward"] = float(
                    np.mean(pending.signal_returns[name])
                )
        for k, v in pending.update_stats.items():
            row[k] = float(np.mean(v))
        if st.curriculum is not None:
            row.update(st.curriculum.summary())
        now = time.perf_counter()
        row["Environment/Steps Per Second"] = (st.step - self._steps_at_t) / max(
            now - self._t_summary, 1e-9
        )
        row["Environment/Elapsed Seconds"] = now - self._t_start
        self._t_summary, self._steps_at_t = now, st.step
        pending.clear()
        return row

    # -- checkpoints ------------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        """Everything an exact resume needs (``checkpoint.py``)."""
        return checkpoint.trainer_state(self.state, self.cfg)

    def load_state_dict(self, s: dict[str, Any]) -> None:
        checkpoint.load_trainer_state(self.state, s)
        self._steps_at_t = self.state.step

    def save_checkpoint(self) -> Path:
        """``checkpoints/step_<step>.pt``; refuses (:class:`NonFiniteLossError`) when a weight
        is not finite, so the last checkpoint on disk is always a good one."""
        for net in self.state.networks().values():
            for name, p in net.named_parameters():
                if not torch.isfinite(p).all():
                    raise NonFiniteLossError(
                        self._nonfinite_message(f"weight {name} is not finite")
                    )
        return run_files.save_checkpoint(
            self.run_dir, self.state.step, self.state_dict(), self.behavior.keep_checkpoints
        )
