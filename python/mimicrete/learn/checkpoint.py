"""What a trainer checkpoint holds, and how a trainer is rebuilt from one (``--resume``).

:func:`trainer_state` gathers the networks, optimisers, the BC rate, the schedules' step, every
random stream, the curriculum, and the vector env's ``state()`` with the per-env running returns
and the scalars not yet summarised; :func:`load_trainer_state` puts them back and checks that the
replayed envs reproduce the stored observations (else :class:`ResumeError`), so that a resumed
run continues bit for bit like the uninterrupted one (``tests/learn/test_exact_resume.py``).
Both read and write a :class:`run_state.RunState`; the keys of the dict are the checkpoint
format (``checkpoints/step_<step>.pt``), kept as it was so that older checkpoints still load.
"""

from __future__ import annotations

import dataclasses
import random
import warnings
from typing import Any

import numpy as np
import torch

from mimicrete._native import MimicreteError

from . import config as config_mod
from .bc import bc_learning_rate
from .episodes import EpisodeResult
from .run_state import RunState


class ResumeError(MimicreteError, RuntimeError):
    """A checkpoint that cannot be resumed exactly (its episodes do not replay)."""


def trainer_state(st: RunState, cfg: config_mod.TrainerConfig) -> dict[str, Any]:
    """The checkpoint of ``st`` (a run of ``cfg``), with the process's random streams."""
    return {
        "actor": st.actor.state_dict(),
        "critic": st.critic.state_dict(),
        "opt": st.opt.state_dict(),
        "gail": st.gail.state_dict() if st.gail is not None else None,
        "bc_opt": st.bc.opt.state_dict() if st.bc is not None else None,
        "bc_lr": st.bc.current_lr if st.bc is not None else None,
        "step": st.step,
        "update_idx": st.update_idx,
        "last_summary_step": st.last_summary_step,
        "converged_streak": st.converged_streak,
        "rng": st.rng.bit_generator.state,
        "torch_rng": torch.get_rng_state(),
        "np_global_rng": np.random.get_state(),
        "py_rng": random.getstate(),
        "curriculum": st.curriculum.state_dict() if st.curriculum is not None else None,
        "signals": st.signals,
        "obs_dim": st.rollout.obs.shape[-1],
        "config": cfg.to_dict(),
        "envs": _envs_state(st),
    }


def _envs_state(st: RunState) -> dict[str, Any] | None:
    """The vector env and everything per env that outlives a rollout (None before the
    first reset)."""
    if st.obs is None:
        return None
    ep, pending = st.episodes, st.pending
    return {
        "env": st.env.state(),
        "obs": st.obs.copy(),
        "episode_ret": ep.ret.copy(),
        "episode_length": ep.length.copy(),
        "episode_picked": ep.picked.copy(),
        "episode_installed": ep.installed.copy(),
        "sig_acc": {k: v.copy() for k, v in st.signal_sums.items()},
        "window": [dataclasses.astuple(e) for e in pending.episodes],
        "sig_window": {k: list(v) for k, v in pending.signal_returns.items()},
        "update_stats": {k: list(v) for k, v in pending.update_stats.items()},
        "recent": (st.recent_picked, st.recent_installed),
    }


def _load_envs_state(st: RunState, s: dict[str, Any] | None) -> None:
    if s is None:
        st.obs = None  # saved before any rollout: reset at the first collect
        return
    obs = np.asarray(st.env.restore(s["env"]), np.float32)
    if not np.array_equal(obs, s["obs"]):
        bad = int(np.flatnonzero((obs != s["obs"]).any(axis=1))[0])
        raise ResumeError(
            f"replaying the checkpoint's running episodes does not reproduce env {bad}'s "
            "observation: the simulator is not the one that wrote the checkpoint, so the "
            "run cannot be resumed exactly"
        )
    st.obs = obs
    ep = st.episodes
    ep.ret[:], ep.length[:] = s["episode_ret"], s["episode_length"]
    ep.picked[:], ep.installed[:] = s["episode_picked"], s["episode_installed"]
    st.signal_sums = {k: np.array(v) for k, v in s["sig_acc"].items()}
    pending = st.pending
    pending.episodes = [EpisodeResult(*e) for e in s["window"]]
    pending.signal_returns = {k: list(v) for k, v in s["sig_window"].items()}
    pending.update_stats = {k: list(v) for k, v in s["update_stats"].items()}
    st.recent_picked, st.recent_installed = s["recent"]


def load_trainer_state(st: RunState, s: dict[str, Any]) -> None:
    """Put checkpoint ``s`` back into ``st`` (and the process's random streams)."""
    st.actor.load_state_dict(s["actor"])
    st.critic.load_state_dict(s["critic"])
    st.opt.load_state_dict(s["opt"])
    if st.gail is not None:
        st.gail.load_state_dict(s["gail"])
    if st.bc is not None:
        st.bc.opt.load_state_dict(s["bc_opt"])
        if s.get("bc_lr") is not None:
            st.bc.current_lr = float(s["bc_lr"])
        else:  # a checkpoint of the older order: the rate its next round would have used
            st.bc.current_lr = bc_learning_rate(
                st.bc.initial_lr, st.bc.steps, int(s["step"]) + st.steps_per_update
            )
    if st.curriculum is not None and s.get("curriculum") is not None:
        st.curriculum.load_state_dict(s["curriculum"])
    st.step = int(s["step"])
    st.update_idx = int(s["update_idx"])
    st.last_summary_step = int(s["last_summary_step"])
    st.converged_streak = int(s.get("converged_streak", 0))
    st.rng.bit_generator.state = s["rng"]
    torch.set_rng_state(s["torch_rng"])
    np.random.set_state(s["np_global_rng"])
    random.setstate(s["py_rng"])
    if "envs" in s:
        _load_envs_state(st, s["envs"])
    else:
        warnings.warn(
            "checkpoint of an older version (no env state): the envs restart with a seed "
            "derived from the update index, so the resumed run is not exact",
            stacklevel=2,
        )
        st.obs = None
