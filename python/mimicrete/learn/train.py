"""``mimicrete train``: BC + GAIL + PPO the way Unity ML-Agents combines them, top to bottom.

One update = collect ``buffer_size`` steps from ``num_envs`` vectorised envs (``buffer_size /
num_envs`` steps each) -> update the observation normalisers -> evaluate every reward signal on
the buffer (extrinsic x strength, GAIL x strength) -> per-signal GAE with that signal's gamma and
value head -> mean of the advantages, z-normalised -> ``num_epoch`` PPO epochs over minibatches of
``batch_size``, each followed by one discriminator step against an expert minibatch of the same
size -> one BC round (while its learning rate is above 1e-10) -> logs, checkpoints, ONNX.

Departures from ML-Agents (and why):
- Trajectories are the rollout's per-env segments of ``buffer_size / num_envs`` steps, cut at
  episode ends and every ``time_horizon`` steps, bootstrapped at every cut that is not a
  termination (truncations bootstrap from ``final_obs``). ML-Agents cuts per agent at
  ``time_horizon`` the same way; only the segment boundaries differ.
- Values used for GAE are recomputed in batch after the rollout, with the normaliser just updated
  (ML-Agents does the same in ``_process_trajectory``); no per-step critic call during rollout.
- At every checkpoint the envs are reset with a seed derived from (seed, update index); running
  episodes are cut there as truncations. This is what makes ``--resume`` exact without
  serialising simulator state.
- Env action = clip(u, -1, 1) instead of ML-Agents' clamp(u, -3, 3)/3 (see ``networks.py``).
- GAIL's survivor bias is handled with ``survivor_bias: bootstrap`` (see ``gail.py``).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import random
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch

from . import config as config_mod
from .bc import BehavioralCloning
from .buffer import Rollout, gae, horizon_cuts
from .gail import Gail, signal_terminated
from .networks import Actor, Critic, DeterministicPolicy, env_action
from .ppo import PPOStats, combine_advantages, ppo_loss, scheduled

N_CONT = 6
TOY_PREFIX = "Toy"

# Scalars written to TensorBoard and to the CSV (ML-Agents' tag names + ours).
TAGS = [
    "Environment/Cumulative Reward",
    "Environment/Episode Length",
    "Environment/Picked Rate",
    "Environment/Installed Rate",
    "Environment/Episodes",
    "Policy/Extrinsic Reward",
    "Policy/GAIL Reward",
    "Policy/Extrinsic Value Estimate",
    "Policy/GAIL Value Estimate",
    "Policy/GAIL Expert Estimate",
    "Policy/GAIL Policy Estimate",
    "Policy/GAIL Grad Mag Loss",
    "Policy/Learning Rate",
    "Policy/Epsilon",
    "Policy/Beta",
    "Policy/Entropy",
    "Losses/Policy Loss",
    "Losses/Value Loss",
    "Losses/GAIL Loss",
    "Losses/Pretraining Loss",
    "Losses/Pretraining Learning Rate",
    "Environment/Steps Per Second",
]


# ----------------------------------------------------------------------------------------------
# environment and demos
# ----------------------------------------------------------------------------------------------


def make_env(env_id: str, num_envs: int, seed: int):
    """``Toy...`` ids give the numpy stand-in (tests); anything else ``mimicrete.envs.make_vec``."""
    if env_id.startswith(TOY_PREFIX):
        from . import toyenv

        return toyenv.make_vec(num_envs, seed=seed)
    from mimicrete import envs  # the Rust-backed env (tile-sim engineer's module)

    return envs.make_vec(env_id, num_envs=num_envs, seed=seed)


def load_demos(path: str, episodes: int | None) -> dict[str, np.ndarray]:
    """Demo arrays from an ``.npz`` (same keys as ``mimicrete.demos.load``) or MCAP file/dir,
    restricted to the first ``episodes`` episodes (in file / episode-index order)."""
    p = Path(path)
    if p.suffix == ".npz":
        with np.load(p) as z:
            d = {k: z[k] for k in z.files}
    else:
        if not p.exists():
            raise FileNotFoundError(
                f"demo path {p} does not exist (make demos with `mimicrete synth-hands` and "
                "`mimicrete convert`, or pass --demos DIR)"
            )
        from mimicrete import demos  # demo-log engineer's module

        d = _demo_arrays(demos.load(str(p)))
    ep = np.asarray(d["episode"])
    if episodes is not None:
        uniq = np.unique(ep)
        if len(uniq) < episodes:
            raise config_mod.ConfigError(
                f"{path}: {len(uniq)} demo episodes, the config asks for {episodes}"
            )
        keep = np.isin(ep, uniq[:episodes])
        d = {k: np.asarray(v)[keep] for k, v in d.items()}
    return d


DEMO_KEYS = ("obs", "actions", "rewards", "terminated", "truncated", "episode")


def idle_steps(actions: np.ndarray, episode: np.ndarray, threshold: float) -> np.ndarray:
    """Mask of the demo steps in which the demonstrator was idle: every joint motion
    ``|a[0:6]|`` below ``threshold`` (a fraction of the env's joint step) and every command after
    the joints (end effector, spin) either 0 ("fixed") or the same as the previous step's in the
    episode, so it changes nothing. A human pauses: after the pick, before the place, while
    deciding. Those steps teach a policy that standing still is what the expert does in a state it
    cannot tell from the moment before moving on, and a five-frame observation cannot tell how
    long a pause has lasted; the policy then freezes there. ``threshold <= 0`` marks nothing."""
    a = np.asarray(actions)
    idle = np.zeros(len(a), bool)
    if threshold <= 0 or len(a) == 0:
        return idle
    ep = np.asarray(episode)
    cmd = a[:, N_CONT:]
    prev = np.vstack([np.full((1, cmd.shape[1]), np.nan), cmd[:-1]])
    prev[np.r_[True, ep[1:] != ep[:-1]]] = np.nan  # no previous command at an episode's start
    no_change = ((cmd == 0) | (cmd == prev)).all(axis=1)
    return (np.abs(a[:, :N_CONT]).max(axis=1) < threshold) & no_change


def drop_idle_steps(d: dict[str, np.ndarray], threshold: float) -> dict[str, np.ndarray]:
    """``d`` without its :func:`idle_steps` (behaviours.<name>.demo_drop_idle, an extension).
    Every kept step keeps the observation it was recorded with, so BC's (obs, action) pairs and
    GAIL's expert states stay true; only the pauses leave."""
    keep = ~idle_steps(d["actions"], d["episode"], threshold)
    return {k: np.asarray(v)[keep] for k, v in d.items()}


def _demo_arrays(loaded: Any) -> dict[str, np.ndarray]:
    """Accept a dict, a NamedTuple, a dataclass / object with attributes, or a plain tuple in the
    order (obs, actions, rewards, terminated, truncated, episode)."""
    if isinstance(loaded, dict):
        src = loaded
    elif hasattr(loaded, "_asdict"):
        src = loaded._asdict()
    elif all(hasattr(loaded, k) for k in DEMO_KEYS):
        src = {k: getattr(loaded, k) for k in DEMO_KEYS}
    elif isinstance(loaded, (tuple, list)) and len(loaded) >= len(DEMO_KEYS):
        src = dict(zip(DEMO_KEYS, loaded, strict=False))
    else:
        raise TypeError(f"mimicrete.demos.load returned {type(loaded).__name__}")
    return {k: np.asarray(src[k]) for k in DEMO_KEYS}


def final_obs_of(infos: dict, ended: np.ndarray) -> np.ndarray:
    """(k, D) terminal observations of the envs where ``ended`` (gymnasium 1.x SAME_STEP)."""
    fo = infos["final_obs"]
    idx = np.flatnonzero(ended)
    if isinstance(fo, np.ndarray) and fo.dtype != object:
        return fo[idx].astype(np.float32)
    return np.stack([np.asarray(fo[i], np.float32) for i in idx])


def episode_flags(infos: dict, rewards: np.ndarray, terminated: np.ndarray):
    """(picked_now, installed_now) per env at this step: the env's flags if it reports them,
    else from the reward (pick: +1 while not terminal; install: terminal with reward > 0)."""
    if "picked" in infos and "installed" in infos:
        return np.asarray(infos["picked"], bool), np.asarray(infos["installed"], bool)
    picked = rewards > 0.5
    installed = terminated & (rewards > 0.5)
    return picked, installed


# ----------------------------------------------------------------------------------------------
# the trainer
# ----------------------------------------------------------------------------------------------


class Trainer:
    def __init__(
        self,
        cfg: config_mod.TrainerConfig,
        run_dir: Path,
        demos_override: str | None,
        max_steps: int,
    ):
        self.cfg = cfg
        self.b = cfg.behavior
        self.h = self.b.hyperparameters
        self.run_dir = run_dir
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

        rs = self.b.reward_signals
        self.signals: list[str] = []
        if rs.extrinsic is not None:
            self.signals.append("extrinsic")
        if rs.gail is not None:
            self.signals.append("gail")

        ns = self.b.network_settings
        self.actor = Actor(self.obs_dim, N_CONT, ns.hidden_units, ns.num_layers, ns.normalize)
        self.critic = Critic(
            self.obs_dim, len(self.signals), ns.hidden_units, ns.num_layers, ns.normalize
        )
        self.opt = torch.optim.Adam(
            list(self.actor.parameters()) + list(self.critic.parameters()), lr=self.h.learning_rate
        )

        self.demos = None
        self.demo_steps_loaded = 0
        need_demos = rs.gail is not None or self.b.behavioral_cloning is not None
        if need_demos:
            path = demos_override or cfg.demo_path
            if not path:
                raise config_mod.ConfigError("gail/behavioral_cloning need a demo_path or --demos")
            self.demos = load_demos(path, self.b.demo_episodes)
            self.demo_steps_loaded = len(self.demos["actions"])
            self.demos = drop_idle_steps(self.demos, self.b.demo_drop_idle)
        self.gail = None
        if rs.gail is not None:
            assert self.demos is not None
            g = rs.gail
            expert_in = self._disc_inputs(self.demos["obs"], self.demos["actions"])
            self.gail = Gail(
                expert_in,
                g.network_settings.hidden_units,
                g.network_settings.num_layers,
                g.learning_rate,
            )
        self.bc = None
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
            )

        self.step = 0
        self.update_idx = 0
        self.last_summary_step = 0
        self.rollout = Rollout(self.T, self.N, self.obs_dim, N_CONT)
        self.obs: np.ndarray | None = None
        self._reset_accumulators()
        self._window: list[tuple[float, int, bool, bool]] = []  # finished episodes since summary
        self._sig_window: dict[str, list[float]] = {s: [] for s in self.signals}
        self._sig_acc = {s: np.zeros(self.N) for s in self.signals}
        self._update_stats: dict[str, list[float]] = {}
        self.recent_installed = 0.0
        self.recent_picked = 0.0
        self._t_summary = time.perf_counter()
        self._steps_at_t = 0

    def pretrain(self) -> None:
        """Offline BC warm start (``behavioral_cloning.pretrain_steps``, a mimicrete extension).
        The observation normalisers are first seeded with the demos' statistics so that the
        warm-started policy sees the same inputs once agent data starts flowing in."""
        bcs = self.b.behavioral_cloning
        if self.bc is None or bcs is None or bcs.pretrain_steps <= 0:
            return
        demo_obs = torch.from_numpy(np.asarray(self.bc.obs))
        self.actor.norm.update(demo_obs)
        self.critic.norm.update(demo_obs)
        losses = self.bc.pretrain(bcs.pretrain_steps, self.rng)
        self._log("Losses/Pretraining Loss", float(np.mean(losses[-50:])))

    # -- helpers --------------------------------------------------------------------------------

    def _disc_inputs(self, obs: np.ndarray, actions: np.ndarray) -> np.ndarray:
        g = self.b.reward_signals.gail
        if g is not None and g.use_actions:
            return np.concatenate([obs, actions], -1).astype(np.float32)
        return np.asarray(obs, np.float32)

    def _reset_accumulators(self) -> None:
        self.ep_ret = np.zeros(self.N)
        self.ep_len = np.zeros(self.N, np.int64)
        self.ep_picked = np.zeros(self.N, bool)
        self.ep_installed = np.zeros(self.N, bool)

    def _reset_envs(self) -> None:
        """Reset every env with a seed derived from (seed, update index)."""
        s = (self.seed * 1_000_003 + self.update_idx * 7919) % 2**31
        self.obs, _ = self.env.reset(seed=s)
        self.obs = np.asarray(self.obs, np.float32)
        self._reset_accumulators()
        self._sig_acc = {k: np.zeros(self.N) for k in self.signals}

    def _log(self, key: str, value: float) -> None:
        self._update_stats.setdefault(key, []).append(float(value))

    # -- rollout ----------------------------------------------------------------------------------

    def collect(self) -> None:
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
            ro.rewards[t] = r
            ro.terminated[t] = term
            ro.truncated[t] = trunc
            picked, installed = episode_flags(infos, r, term)
            self.ep_ret += r
            self.ep_len += 1
            self.ep_picked |= picked
            self.ep_installed |= installed
            ended = term | trunc
            if ended.any():
                ro.final_obs[t, ended] = final_obs_of(infos, ended)
                for i in np.flatnonzero(ended):
                    self._window.append(
                        (
                            float(self.ep_ret[i]),
                            int(self.ep_len[i]),
                            bool(self.ep_picked[i]),
                            bool(self.ep_installed[i]),
                        )
                    )
                self.ep_ret[ended] = 0.0
                self.ep_len[ended] = 0
                self.ep_picked[ended] = False
                self.ep_installed[ended] = False
            obs = np.asarray(nobs, np.float32)
        ro.last_obs[:] = obs
        self.obs = obs
        self.step += self.T * self.N

    # -- update -----------------------------------------------------------------------------------

    def process(self) -> dict[str, np.ndarray]:
        """Normaliser update, reward signals, values and per-signal GAE -> flat update buffer."""
        ro = self.rollout
        T, N, D = self.T, self.N, self.obs_dim
        obs_flat = torch.from_numpy(ro.obs.reshape(T * N, D))
        self.actor.norm.update(obs_flat)
        self.critic.norm.update(obs_flat)
        next_obs = torch.from_numpy(ro.next_obs().reshape(T * N, D))
        with torch.no_grad():
            values = self.critic(obs_flat).numpy().reshape(T, N, -1).astype(np.float64)
            next_values = self.critic(next_obs).numpy().reshape(T, N, -1).astype(np.float64)
        cut = ro.ended | horizon_cuts(T, N, self.b.time_horizon)
        rs = self.b.reward_signals
        advs, rets = [], []
        for i, name in enumerate(self.signals):
            if name == "extrinsic":
                assert rs.extrinsic is not None
                r = rs.extrinsic.strength * ro.rewards.astype(np.float64)
                gamma = rs.extrinsic.gamma
                term = ro.terminated
                self._log("Policy/Extrinsic Value Estimate", values[..., i].mean())
            else:
                assert rs.gail is not None and self.gail is not None
                x = self._disc_inputs(ro.obs.reshape(T * N, D), ro.env_actions.reshape(T * N, -1))
                r = rs.gail.strength * self.gail.rewards(torch.from_numpy(x)).reshape(T, N)
                r = r.astype(np.float64)
                gamma = rs.gail.gamma
                term = signal_terminated(ro.terminated, rs.gail.survivor_bias)
                self._log("Policy/GAIL Value Estimate", values[..., i].mean())
            self._episode_signal_sums(name, r)
            a, ret = gae(r, values[..., i], next_values[..., i], term, cut, gamma, self.h.lambd)
            advs.append(a)
            rets.append(ret)
        adv = combine_advantages(advs)
        return {
            "obs": ro.obs.reshape(T * N, D),
            "u": ro.u.reshape(T * N, N_CONT),
            "k": ro.k.reshape(T * N),
            "logp": ro.logp.reshape(T * N, N_CONT + 1),
            "env_actions": ro.env_actions.reshape(T * N, N_CONT + 1),
            "adv": adv.reshape(T * N).astype(np.float32),
            "values": values.reshape(T * N, -1).astype(np.float32),
            "returns": np.stack(rets, -1).reshape(T * N, -1).astype(np.float32),
        }

    def _episode_signal_sums(self, name: str, r: np.ndarray) -> None:
        """Per-episode sums of a (strength-scaled) signal, as ML-Agents' Policy/<Signal> Reward."""
        acc = self._sig_acc[name]
        ended = self.rollout.ended
        for t in range(self.T):
            acc += r[t]
            if ended[t].any():
                self._sig_window[name].extend(acc[ended[t]].tolist())
                acc[ended[t]] = 0.0

    def update(self, buf: dict[str, np.ndarray]) -> None:
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
        t = {k: torch.from_numpy(v) for k, v in buf.items()}
        n = len(buf["adv"])
        bs = h.batch_size
        stats = PPOStats()
        for _ in range(h.num_epoch):
            perm = torch.as_tensor(self.rng.permutation(n))
            for s in range(0, n - bs + 1, bs):
                idx = perm[s : s + bs]
                loss, (pl, vl, ent) = ppo_loss(
                    self.actor,
                    self.critic,
                    t["obs"][idx],
                    t["u"][idx],
                    t["k"][idx],
                    t["logp"][idx],
                    t["adv"][idx],
                    t["values"][idx],
                    t["returns"][idx],
                    eps,
                    beta,
                )
                self.opt.zero_grad()
                loss.backward()
                self.opt.step()
                stats.add(pl, vl, ent)
                if self.gail is not None:
                    x = self._disc_inputs(buf["obs"][idx.numpy()], buf["env_actions"][idx.numpy()])
                    gs = self.gail.update(torch.from_numpy(x), self.rng)
                    self._log("Losses/GAIL Loss", gs["loss"])
                    self._log("Policy/GAIL Grad Mag Loss", gs["grad_penalty"])
                    self._log("Policy/GAIL Expert Estimate", gs["expert_estimate"])
                    self._log("Policy/GAIL Policy Estimate", gs["policy_estimate"])
        m = stats.mean()
        self._log("Losses/Policy Loss", abs(m["policy_loss"]))
        self._log("Losses/Value Loss", m["value_loss"])
        self._log("Policy/Entropy", m["entropy"])
        if self.bc is not None:
            res = self.bc.update(self.step, self.rng)
            if res is not None:
                self._log("Losses/Pretraining Loss", res[0])
                self._log("Losses/Pretraining Learning Rate", res[1])
        self.update_idx += 1

    # -- logging ----------------------------------------------------------------------------------

    def summary(self) -> dict[str, float] | None:
        """Scalars since the last summary (None if nothing to report)."""
        row: dict[str, float] = {}
        if self._window:
            rets, lens, picked, inst = zip(*self._window, strict=True)
            row["Environment/Cumulative Reward"] = float(np.mean(rets))
            row["Environment/Episode Length"] = float(np.mean(lens))
            row["Environment/Picked Rate"] = float(np.mean(picked))
            row["Environment/Installed Rate"] = float(np.mean(inst))
            row["Environment/Episodes"] = float(len(rets))
            self.recent_installed = row["Environment/Installed Rate"]
            self.recent_picked = row["Environment/Picked Rate"]
        for name, tag in (("extrinsic", "Policy/Extrinsic Reward"), ("gail", "Policy/GAIL Reward")):
            if self._sig_window.get(name):
                row[tag] = float(np.mean(self._sig_window[name]))
        for k, v in self._update_stats.items():
            row[k] = float(np.mean(v))
        now = time.perf_counter()
        row["Environment/Steps Per Second"] = (self.step - self._steps_at_t) / max(
            now - self._t_summary, 1e-9
        )
        self._t_summary, self._steps_at_t = now, self.step
        self._window.clear()
        for v in self._sig_window.values():
            v.clear()
        self._update_stats.clear()
        return row

    # -- checkpoints ------------------------------------------------------------------------------

    def state_dict(self) -> dict[str, Any]:
        return {
            "actor": self.actor.state_dict(),
            "critic": self.critic.state_dict(),
            "opt": self.opt.state_dict(),
            "gail": self.gail.state_dict() if self.gail is not None else None,
            "bc_opt": self.bc.opt.state_dict() if self.bc is not None else None,
            "step": self.step,
            "update_idx": self.update_idx,
            "last_summary_step": self.last_summary_step,
            "rng": self.rng.bit_generator.state,
            "torch_rng": torch.get_rng_state(),
            "np_global_rng": np.random.get_state(),
            "py_rng": random.getstate(),
            "signals": self.signals,
            "obs_dim": self.obs_dim,
            "config": self.cfg.to_dict(),
        }

    def load_state_dict(self, s: dict[str, Any]) -> None:
        self.actor.load_state_dict(s["actor"])
        self.critic.load_state_dict(s["critic"])
        self.opt.load_state_dict(s["opt"])
        if self.gail is not None:
            self.gail.load_state_dict(s["gail"])
        if self.bc is not None:
            self.bc.opt.load_state_dict(s["bc_opt"])
        self.step = int(s["step"])
        self.update_idx = int(s["update_idx"])
        self.last_summary_step = int(s["last_summary_step"])
        self.rng.bit_generator.state = s["rng"]
        torch.set_rng_state(s["torch_rng"])
        np.random.set_state(s["np_global_rng"])
        random.setstate(s["py_rng"])
        self._steps_at_t = self.step
        self.obs = None  # envs are reset with the (seed, update index) seed, as after a save

    def save_checkpoint(self) -> Path:
        ck_dir = self.run_dir / "checkpoints"
        ck_dir.mkdir(parents=True, exist_ok=True)
        path = ck_dir / f"step_{self.step:09d}.pt"
        tmp = path.with_suffix(".tmp")
        torch.save(self.state_dict(), tmp)
        os.replace(tmp, path)
        export_onnx(self.actor, self.obs_dim, ck_dir / f"step_{self.step:09d}.onnx")
        ckpts = sorted(ck_dir.glob("step_*.pt"))
        for old in ckpts[: max(0, len(ckpts) - max(1, self.b.keep_checkpoints))]:
            old.unlink()
            onnx_old = old.with_suffix(".onnx")
            if onnx_old.exists():
                onnx_old.unlink()
        self.obs = None  # checkpoint boundary: envs are reset (see module docstring)
        return path


def latest_checkpoint(run_dir: Path) -> Path | None:
    ckpts = sorted((run_dir / "checkpoints").glob("step_*.pt"))
    return ckpts[-1] if ckpts else None


def export_onnx(actor: Actor, obs_dim: int, path: Path) -> None:
    """The deterministic policy as ONNX: input ``obs`` (B, obs_dim) float32 -> ``actions``
    (B, 7) float32 (6 joint motions in [-1, 1], EE command in {-1, 0, 1})."""
    import copy
    import io

    model = DeterministicPolicy(copy.deepcopy(actor)).eval()
    dummy = torch.zeros(1, obs_dim)
    buf = io.BytesIO()
    with warnings.catch_warnings():  # the TorchScript exporter warns it is deprecated
        warnings.simplefilter("ignore")
        torch.onnx.export(
            model,
            (dummy,),
            buf,
            input_names=["obs"],
            output_names=["actions"],
            dynamic_axes={"obs": {0: "batch"}, "actions": {0: "batch"}},
            opset_version=17,
            dynamo=False,
        )
    tmp = path.with_suffix(".onnx.tmp")
    tmp.write_bytes(buf.getvalue())
    os.replace(tmp, path)


class ScalarLog:
    """TensorBoard + CSV writer of the same scalars."""

    def __init__(self, run_dir: Path, resume: bool):
        from torch.utils.tensorboard import SummaryWriter

        self.tb = SummaryWriter(str(run_dir / "tensorboard"))
        self.csv_path = run_dir / "scalars.csv"
        if not (resume and self.csv_path.exists()):
            with open(self.csv_path, "w", newline="") as f:
                csv.writer(f).writerow(["step", *TAGS])

    def write(self, step: int, row: dict[str, float]) -> None:
        for k, v in row.items():
            self.tb.add_scalar(k, v, step)
        self.tb.flush()
        with open(self.csv_path, "a", newline="") as f:
            csv.writer(f).writerow([step, *[_fmt(row.get(t)) for t in TAGS]])

    def close(self) -> None:
        self.tb.close()


def _fmt(v: float | None) -> str:
    return "" if v is None or not math.isfinite(v) else repr(float(v))


def train(
    cfg: config_mod.TrainerConfig,
    run_dir: Path,
    *,
    demos: str | None = None,
    resume: bool = False,
    max_steps: int | None = None,
    progress: bool = True,
    stop_after_updates: int | None = None,
) -> Trainer:
    """Run (or resume) training; returns the trainer. ``stop_after_updates`` ends early without
    changing the schedules (for tests of resume)."""
    run_dir.mkdir(parents=True, exist_ok=True)
    total = int(max_steps if max_steps is not None else cfg.behavior.max_steps)
    config_mod.save(cfg, run_dir / "resolved_config.yaml")
    tr = Trainer(cfg, run_dir, demos, total)
    info: dict[str, Any] = {"max_steps": total, "demos": demos or cfg.demo_path}
    if tr.demos is not None:
        info["demo_steps_loaded"] = tr.demo_steps_loaded
        info["demo_steps_idle_dropped"] = tr.demo_steps_loaded - len(tr.demos["actions"])
    (run_dir / "run.json").write_text(json.dumps(info, indent=1))
    if resume:
        ck = latest_checkpoint(run_dir)
        if ck is None:
            raise FileNotFoundError(f"--resume: no checkpoint in {run_dir / 'checkpoints'}")
        tr.load_state_dict(torch.load(ck, weights_only=False))
    else:
        tr.pretrain()
    log = ScalarLog(run_dir, resume)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(
            total=total,
            initial=tr.step,
            unit="step",
            dynamic_ncols=True,
            file=sys.stderr,
            smoothing=0.1,
        )
    ck_every = max(cfg.behavior.checkpoint_interval, 1)
    next_ck = (tr.step // ck_every + 1) * ck_every
    updates = 0
    try:
        while tr.step < total:
            before = tr.step
            tr.collect()
            buf = tr.process()
            tr.update(buf)
            updates += 1
            if tr.step - tr.last_summary_step >= cfg.behavior.summary_freq or tr.step >= total:
                row = tr.summary()
                if row:
                    log.write(tr.step, row)
                tr.last_summary_step = tr.step
            if tr.step >= next_ck or tr.step >= total:
                tr.save_checkpoint()
                next_ck = (tr.step // ck_every + 1) * ck_every
            if bar is not None:
                bar.update(tr.step - before)
                bar.set_postfix(
                    picked=f"{tr.recent_picked:.0%}", installed=f"{tr.recent_installed:.0%}"
                )
            if stop_after_updates is not None and updates >= stop_after_updates:
                break
    finally:
        if bar is not None:
            bar.close()
        log.close()
        tr.env.close()
    export_onnx(tr.actor, tr.obs_dim, run_dir / "policy.onnx")
    torch.save(
        {
            "actor": tr.actor.state_dict(),
            "obs_dim": tr.obs_dim,
            "step": tr.step,
            "config": cfg.to_dict(),
        },
        run_dir / "policy.pt",
    )
    return tr


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------

DEFAULT_GROUP = "group3.yaml"  # Table 5's best pair is groups 3 and 4; with the hand-derived demos
# both installed 100 % on 3 of 3 seeds here, group 3 sooner (328k-420k steps to 97 %) and shorter
DEFAULT_MAX_STEPS = 1_000_000  # the budget when no config is named
DEFAULT_DEMOS = "demos/suction"


def find_config_dir() -> Path:
    here = Path(__file__).resolve()
    for cand in (Path.cwd() / "configs", here.parents[3] / "configs"):
        if cand.is_dir():
            return cand
    raise FileNotFoundError("no configs/ directory (looked in ./configs and the repo root)")


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config",
        help=f"ML-Agents-shaped YAML (default configs/{DEFAULT_GROUP}"
        f" with --max-steps {DEFAULT_MAX_STEPS})",
    )
    parser.add_argument(
        "--demos",
        help="demo dir/file; overrides the config's demo_path "
        f"(default: the config's, i.e. {DEFAULT_DEMOS})",
    )
    parser.add_argument("--run-dir", help="default runs/<config name>-seed<seed>")
    parser.add_argument("--resume", action="store_true", help="continue from the latest checkpoint")
    parser.add_argument("--seed", type=int, help="override env_settings.seed")
    parser.add_argument("--max-steps", type=int, help="override max_steps (schedules follow it)")
    parser.add_argument("--num-envs", type=int, help="override env_settings.num_envs")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override any config key, e.g. behavior.reward_signals.gail."
        "survivor_bias=none (repeatable)",
    )
    parser.add_argument(
        "--eval-episodes",
        type=int,
        default=100,
        help="evaluate the final policy on this many episodes (0: skip)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    if args.config is None:
        cfg_path = find_config_dir() / DEFAULT_GROUP
        max_steps = args.max_steps if args.max_steps is not None else DEFAULT_MAX_STEPS
    else:
        cfg_path = Path(args.config)
        max_steps = args.max_steps
    cfg = config_mod.load(cfg_path)
    overrides = list(args.set)
    if args.seed is not None:
        overrides.append(f"env_settings.seed={args.seed}")
    if args.num_envs is not None:
        overrides.append(f"env_settings.num_envs={args.num_envs}")
    if max_steps is not None:
        overrides.append(f"behavior.max_steps={max_steps}")
    if overrides:
        cfg = config_mod.with_overrides(cfg, overrides)
    run_dir = Path(args.run_dir or f"runs/{cfg_path.stem}-seed{cfg.env_settings.seed}")
    t0 = time.perf_counter()
    try:
        tr = train(
            cfg, run_dir, demos=args.demos, resume=args.resume, progress=not args.no_progress
        )
    except (FileNotFoundError, config_mod.ConfigError) as e:  # demos, checkpoint, too few demos
        print(f"error: {e}", file=sys.stderr)
        return 2
    print(f"trained {tr.step} steps in {time.perf_counter() - t0:.0f} s -> {run_dir}")
    from . import plots

    for p in plots.learning_curves(run_dir):
        print(f"plot: {p}")
    if args.eval_episodes > 0:
        from . import evaluate

        res = evaluate.evaluate_run(run_dir, args.eval_episodes)
        print(evaluate.format_row(run_dir.name, res))
    return 0
