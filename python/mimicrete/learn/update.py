"""One training update of BC + GAIL + PPO, the way Unity ML-Agents combines them, read top to
bottom as in CleanRL. :func:`one_update` is the whole of it; the functions below it come in the
order it calls them:

1. :func:`collect_rollout`: ``buffer_size`` steps from ``num_envs`` vectorised envs
   (``buffer_size / num_envs`` each), the stochastic policy acting; finished episodes go to the
   next summary.
2. :func:`reward_signals`: the observation normalisers take the new observations first; then each
   signal on the rollout, scaled by its strength: extrinsic (the env's reward) and GAIL
   (-log(1 - D), from the discriminator as the rollout found it), each with its own gamma and
   termination mask.
3. :func:`minibatch_plan`: every random draw of the steps that follow, taken before any of them
   runs: per epoch a shuffle of the buffer cut into minibatches, and with GAIL each minibatch's
   expert rows and gradient-penalty weights.
4. :func:`update_discriminator`: GAIL, one discriminator step per PPO minibatch (ML-Agents'
   schedule), against an expert minibatch of the same size. The steps read only the rollout and
   the demos, never the policy, so with ``torch_settings.overlap_gail`` they run on a second
   thread beside steps 5 to 7; their randomness is in the plan, so the numbers are the same.
5. :func:`advantages`: GAE per signal, with that signal's value head, bootstrapped at every cut
   that is not a termination (a truncation from ``final_obs``); the advantage is the mean over
   signals, z-normalised; each head regresses its own returns.
6. :func:`ppo_update`: ``num_epoch`` epochs over the plan's minibatches of ``batch_size``; the
   schedules (learning rate, epsilon, beta) follow the env step.
7. :func:`bc_update`: one round over the demos (while its learning rate is above 1e-10).
8. :func:`log_discriminator`: step 4's scalars, once its steps are done.

Every scalar goes to ``state.pending``, which the next summary averages (``Trainer.summary``).

Departures from ML-Agents (and why):
- Trajectories are the rollout's per-env segments of ``buffer_size / num_envs`` steps, cut at
  episode ends and every ``time_horizon`` steps, bootstrapped at every cut that is not a
  termination (truncations bootstrap from ``final_obs``). ML-Agents cuts per agent at
  ``time_horizon`` the same way; only the segment boundaries differ.
- Values used for GAE are recomputed in batch after the rollout, with the normaliser just updated
  (ML-Agents does the same in ``_process_trajectory``); no per-step critic call during rollout.
- Env action = clip(u, -1, 1) instead of ML-Agents' clamp(u, -3, 3)/3 (see ``networks.py``).
- GAIL's survivor bias is handled with ``survivor_bias: bootstrap`` (see ``gail.py``).
- The envs are reset once, at the start of a run, with a seed derived from the run's seed
  (:func:`reset_envs`); after that every env resets itself when its episode ends, so episodes run
  across updates and checkpoints (``checkpoint.py``) as if there were none.
"""

from __future__ import annotations

import math
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import torch

from mimicrete._native import MimicreteError

from . import config as config_mod
from .buffer import Signal, UpdateBuffer, gae, horizon_cuts
from .env import N_CONT, final_obs_of
from .episodes import EpisodeResult
from .gail import Gail, signal_terminated
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
from .run_state import RunState, disc_inputs

SIGNAL_TAG = {"extrinsic": "Extrinsic", "gail": "GAIL"}  # Policy/<tag> Reward, Value Estimate, ...

#: what one discriminator step reports (``gail.discriminator_loss``'s scalars)
DiscriminatorStats = dict[str, float]


class NonFiniteLossError(MimicreteError, RuntimeError):
    """A loss or weight became NaN / infinite; the run stops before writing anything from it."""


def one_update(
    st: RunState,
    b: config_mod.BehaviorConfig,
    max_steps: int,
    seed: int,
    gail_thread: ThreadPoolExecutor | None = None,
) -> None:
    """One update of the run in ``st``, configured by ``b``; ``max_steps`` sets the schedules,
    ``seed`` the envs' first reset, ``gail_thread`` (or None) runs the discriminator's steps."""
    hp = b.hyperparameters
    collect_rollout(st, seed)  # 1.
    signals = reward_signals(st, b.reward_signals)  # 2.
    plan = minibatch_plan(st, hp.batch_size, hp.num_epoch)  # 3.
    discriminator = update_discriminator(st, b.reward_signals.gail, plan, gail_thread)  # 4.
    buf = advantages(st, signals, b.time_horizon, hp.lambd)  # 5.
    ppo_update(st, buf, plan, hp, max_steps)  # 6.
    bc_update(st)  # 7.
    log_discriminator(st, discriminator.result())  # 8.
    st.update_idx += 1


# -- 1. rollout -----------------------------------------------------------------------------------


def collect_rollout(st: RunState, seed: int) -> None:
    """``T`` steps of every env into ``st.rollout``; episodes that end go to the pending summary
    (or, for those the curriculum started inside a demo, to the curriculum)."""
    ro, cur = st.rollout, st.curriculum
    if st.obs is None:
        reset_envs(st, seed)
    obs = st.obs
    assert obs is not None
    for t in range(ro.T):
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
        _record_finished(st, finished)
        if cur is not None and (env_ended | cut).any():
            cur.restart(st.env, env_ended | cut, cut, nobs)
        obs = nobs
    ro.last_obs[:] = obs
    st.obs = obs
    st.step += ro.T * ro.N


def _record_finished(st: RunState, finished: list[tuple[int, EpisodeResult]]) -> None:
    """Episodes that ended, as (env index, result): one that started at the env's own start goes
    to the pending summary (and the curriculum's record of own starts), one that started inside
    a demo to the curriculum only."""
    cur = st.curriculum
    for i, ep in finished:
        d = -1 if cur is None else int(cur.env_demo[i])
        if d < 0:
            st.pending.episodes.append(ep)
            if cur is not None:
                cur.record_own(i, ep.installed)
        else:
            assert cur is not None
            cur.record(d, ep.installed, bool(cur.env_frontier[i]))


def reset_envs(st: RunState, seed: int) -> None:
    """Reset every env with a seed derived from (``seed``, update index): at the run's start (a
    checkpoint of an older version, without env state, resumes here too)."""
    s = (seed * 1_000_003 + st.update_idx * 7919) % 2**31
    obs, _ = st.env.reset(seed=s)
    st.obs = np.asarray(obs, np.float32)
    st.episodes.reset()
    st.reset_signal_sums()
    if st.curriculum is not None:  # some envs start inside a demo right away
        st.curriculum.forget_envs()
        every = np.ones(st.rollout.N, bool)
        st.curriculum.restart(st.env, every, ~every, st.obs)


# -- 2. reward signals ----------------------------------------------------------------------------


def reward_signals(st: RunState, rs: config_mod.RewardSignals) -> list[Signal]:
    """Update the observation normalisers with the rollout, then every reward signal on it
    (strength-scaled); per-episode sums go to ``Policy/<Signal> Reward``."""
    ro = st.rollout
    obs_flat = torch.from_numpy(_flat(ro.obs))
    st.actor.norm.update(obs_flat)
    st.critic.norm.update(obs_flat)
    out = []
    for name in st.signals:
        if name == "extrinsic":
            assert rs.extrinsic is not None
            r = rs.extrinsic.strength * ro.rewards.astype(np.float64)
            sig = Signal(name, r, rs.extrinsic.gamma, ro.terminated)
        else:
            assert rs.gail is not None and st.gail is not None
            x = disc_inputs(rs.gail, _flat(ro.obs), _flat(ro.env_actions))
            r = rs.gail.strength * st.gail.rewards(torch.from_numpy(x)).reshape(ro.T, ro.N)
            term = signal_terminated(ro.terminated, rs.gail.survivor_bias)
            sig = Signal(name, r.astype(np.float64), rs.gail.gamma, term)
        _add_episode_sums(st, sig)
        out.append(sig)
    return out


def _add_episode_sums(st: RunState, sig: Signal) -> None:
    """Per-episode sums of a (strength-scaled) signal, as ML-Agents' Policy/<Signal> Reward."""
    acc = st.signal_sums[sig.name]
    ended = st.rollout.ended
    for t in range(st.rollout.T):
        acc += sig.rewards[t]
        if ended[t].any():
            st.pending.signal_returns[sig.name].extend(acc[ended[t]].tolist())
            acc[ended[t]] = 0.0


# -- 3. the minibatches ---------------------------------------------------------------------------


@dataclass
class MinibatchPlan:
    """An update's minibatches and the discriminator's randomness, drawn before any step runs.

    ``epochs[e]`` are the buffer rows of epoch ``e``'s PPO minibatches (a shuffle cut into pieces
    of ``batch_size``; a rest smaller than that is left out); ``expert_draws[e][i]`` is what the
    discriminator step on minibatch ``epochs[e][i]`` draws (:meth:`gail.Gail.draw`), empty
    without GAIL."""

    epochs: list[list[torch.Tensor]]
    expert_draws: list[list[tuple[torch.Tensor, torch.Tensor]]]


def minibatch_plan(st: RunState, batch_size: int, num_epoch: int) -> MinibatchPlan:
    """Epoch by epoch: the shuffle (from ``st.rng``), then each minibatch's expert rows (``st.rng``)
    and penalty weights (torch's generator): the order in which the steps would draw them run
    interleaved, one discriminator step after each PPO step (ML-Agents' schedule). No PPO step
    draws anything, so drawing first changes no number."""
    n = st.steps_per_update
    plan = MinibatchPlan([], [])
    for _ in range(num_epoch):
        perm = torch.as_tensor(st.rng.permutation(n))
        batches = [perm[s : s + batch_size] for s in range(0, n - batch_size + 1, batch_size)]
        plan.epochs.append(batches)
        if st.gail is not None:
            plan.expert_draws.append([st.gail.draw(batch_size, st.rng) for _ in batches])
    return plan


# -- 4. GAIL's discriminator ----------------------------------------------------------------------


def update_discriminator(
    st: RunState,
    g: config_mod.GailSettings | None,
    plan: MinibatchPlan,
    thread: ThreadPoolExecutor | None,
) -> Future[list[DiscriminatorStats]]:
    """One discriminator step per minibatch of ``plan``: on ``thread`` while the update goes on,
    or here and now without one. The rewards of this rollout were taken before (step 2). Returns
    the steps' scalars, for :func:`log_discriminator` (none without GAIL)."""
    ro = st.rollout
    done: Future[list[DiscriminatorStats]] = Future()
    if st.gail is None:
        done.set_result([])
        return done
    assert g is not None
    steps = (st.gail, disc_inputs(g, _flat(ro.obs), _flat(ro.env_actions)), plan)
    if thread is not None:
        return thread.submit(discriminator_steps, *steps)
    done.set_result(discriminator_steps(*steps))
    return done


def discriminator_steps(
    gail: Gail, policy_inputs: np.ndarray, plan: MinibatchPlan
) -> list[DiscriminatorStats]:
    """The discriminator's steps, epoch by epoch, each on the rows ``policy_inputs[minibatch]``
    (the rollout's discriminator inputs) with its draw; touches no random generator."""
    out = []
    for batches, draws in zip(plan.epochs, plan.expert_draws, strict=True):
        for mb_inds, draw in zip(batches, draws, strict=True):
            x = policy_inputs[mb_inds.numpy()]
            out.append(gail.step(torch.from_numpy(x), draw))
    return out


# -- 5. GAE ---------------------------------------------------------------------------------------


def advantages(
    st: RunState, signals: list[Signal], time_horizon: int, lambd: float
) -> UpdateBuffer:
    """Per-signal GAE with the signal's gamma and value head; the combined advantage; the flat
    buffer PPO reads.

    ``values`` are V(s_t), ``next_values`` V of the true next state: the next row of the rollout,
    or ``final_obs`` where the episode ended at t (the env has already put the next episode's
    first observation in the row), or the observation after the rollout. Segments are cut at
    episode ends, every ``time_horizon`` steps and at the rollout's end; a cut stops the
    advantage from flowing back across it, and only a termination (in the signal's own mask)
    drops the bootstrap V(s_{t+1}): a truncation or a horizon cut bootstraps from it."""
    ro = st.rollout
    with torch.no_grad():
        v32, nv32 = ro.values_and_next(lambda x: st.critic(torch.from_numpy(x)).numpy())
    values, next_values = v32.astype(np.float64), nv32.astype(np.float64)
    cut = ro.ended | horizon_cuts(ro.T, ro.N, time_horizon)
    advs, rets = [], []
    for i, sig in enumerate(signals):
        v = values[..., i]
        a, ret = gae(sig.rewards, v, next_values[..., i], sig.terminated, cut, sig.gamma, lambd)
        tag = SIGNAL_TAG[sig.name]
        st.pending.log(f"Policy/{tag} Value Estimate", v.mean())
        st.pending.log(f"Policy/{tag} Explained Variance", explained_variance(v, ret))
        advs.append(a)
        rets.append(ret)
    adv = combine_advantages(advs)
    return UpdateBuffer(
        obs=_flat(ro.obs),
        u=ro.u.reshape(-1, N_CONT),
        k=_flat(ro.k),
        logp=_flat(ro.logp),
        env_actions=_flat(ro.env_actions),
        adv=adv.reshape(-1).astype(np.float32),
        values=_flat(values).astype(np.float32),
        returns=_flat(np.stack(rets, -1)).astype(np.float32),
    )


def _flat(x: np.ndarray) -> np.ndarray:
    """(T, N, ...) -> (T * N, ...): a view of the rollout's array, one row per step."""
    return x.reshape(x.shape[0] * x.shape[1], *x.shape[2:])


# -- 6. PPO ---------------------------------------------------------------------------------------


def ppo_update(
    st: RunState,
    buf: UpdateBuffer,
    plan: MinibatchPlan,
    hp: config_mod.Hyperparameters,
    max_steps: int,
) -> None:
    """PPO's epochs over the plan's minibatches, one Adam step each; the learning rate, epsilon
    and beta at this env step (linear over ``max_steps`` unless constant)."""
    log = st.pending.log
    at = (st.step, max_steps)
    lr = scheduled(hp.learning_rate_schedule, "linear", hp.learning_rate, 1e-10, *at)
    eps = scheduled(hp.epsilon_schedule, hp.learning_rate_schedule, hp.epsilon, 0.1, *at)
    beta = scheduled(hp.beta_schedule, hp.learning_rate_schedule, hp.beta, 1e-5, *at)
    for g in st.opt.param_groups:
        g["lr"] = lr
    log("Policy/Learning Rate", lr)
    log("Policy/Epsilon", eps)
    log("Policy/Beta", beta)
    b_t = buf.tensors()
    stats = PPOStats()
    for batches in plan.epochs:
        for mb_inds in batches:
            stats.add(ppo_step(st, b_t, mb_inds, eps, beta))
    m = stats.mean()
    log("Losses/Policy Loss", abs(m["policy_loss"]))
    log("Losses/Value Loss", m["value_loss"])
    log("Policy/Entropy", m["entropy"])
    log("Policy/Approx KL", m["approx_kl"])
    log("Policy/Clip Fraction", m["clipfrac"])


def ppo_step(
    st: RunState, b_t: dict[str, torch.Tensor], mb_inds: torch.Tensor, eps: float, beta: float
) -> PPOLossInfo:
    """One Adam step of PPO's loss on the minibatch ``mb_inds`` of the update buffer ``b_t``."""
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
    check_finite("PPO", loss.item())
    st.opt.zero_grad()
    loss.backward()
    st.opt.step()
    return info


# -- 7. BC ----------------------------------------------------------------------------------------


def bc_update(st: RunState) -> None:
    """One BC round over the demos (``bc.BehavioralCloning.update``), if the run has BC."""
    if st.bc is None:
        return
    res = st.bc.update(st.step, st.rng)
    if res is not None:
        check_finite("BC", res[0])
        st.pending.log("Losses/Pretraining Loss", res[0])
        st.pending.log("Losses/Pretraining Learning Rate", res[1])


# -- 8. the discriminator's scalars ---------------------------------------------------------------


def log_discriminator(st: RunState, steps: list[DiscriminatorStats]) -> None:
    """The scalars of step 4's discriminator steps, in the order they ran."""
    log = st.pending.log
    for gs in steps:
        check_finite("GAIL", gs["loss"])
        log("Losses/GAIL Loss", gs["loss"])
        log("Policy/GAIL Grad Mag Loss", gs["grad_penalty"])
        log("Policy/GAIL Expert Estimate", gs["expert_estimate"])
        log("Policy/GAIL Policy Estimate", gs["policy_estimate"])


def check_finite(what: str, loss: float) -> None:
    """:class:`NonFiniteLossError` when ``loss`` is NaN or infinite (before any step uses it)."""
    if not math.isfinite(loss):
        raise NonFiniteLossError(f"the {what} loss is {loss}")
