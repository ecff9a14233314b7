"""What a trainer checkpoint holds, and how a trainer is rebuilt from one (``--resume``).

:func:`trainer_state` gathers the networks, optimisers, the BC rate, the schedules' step, every
random stream, the curriculum, and the vector env's ``state()`` with the per-env running returns
and the scalars not yet summarised; :func:`load_trainer_state` puts them back and checks that the
replayed envs reproduce the stored observations (else :class:`ResumeError`), so that a resumed
run continues bit for bit like the uninterrupted one (``tests/learn/test_exact_resume.py``).
``self`` below is a ``trainer.Trainer`` (not imported: the trainer imports this module).
"""

from __future__ import annotations

import dataclasses
import random
import warnings
from typing import Any

import numpy as np
import torch

from mimicrete._native import MimicreteError

from .bc import bc_learning_rate
from .episodes import Episode


class ResumeError(MimicreteError, RuntimeError):
    """A checkpoint that cannot be resumed exactly (its episodes do not replay)."""


def trainer_state(self: Any) -> dict[str, Any]:
    return {
        "actor": self.actor.state_dict(),
        "critic": self.critic.state_dict(),
        "opt": self.opt.state_dict(),
        "gail": self.gail.state_dict() if self.gail is not None else None,
        "bc_opt": self.bc.opt.state_dict() if self.bc is not None else None,
        "bc_lr": self.bc.current_lr if self.bc is not None else None,
        "step": self.step,
        "update_idx": self.update_idx,
        "last_summary_step": self.last_summary_step,
        "converged_streak": self.converged_streak,
        "rng": self.rng.bit_generator.state,
        "torch_rng": torch.get_rng_state(),
        "np_global_rng": np.random.get_state(),
        "py_rng": random.getstate(),
        "curriculum": self.curriculum.state_dict() if self.curriculum is not None else None,
        "signals": self.signals,
        "obs_dim": self.obs_dim,
        "config": self.cfg.to_dict(),
        "envs": _envs_state(self),
    }


def _envs_state(self: Any) -> dict[str, Any] | None:
    """The vector env and everything per env that outlives a rollout (None before the
    first reset)."""
    if self.obs is None:
        return None
    ep = self.episodes
    return {
        "env": self.env.state(),
        "obs": self.obs.copy(),
        "episode_ret": ep.ret.copy(),
        "episode_length": ep.length.copy(),
        "episode_picked": ep.picked.copy(),
        "episode_installed": ep.installed.copy(),
        "sig_acc": {k: v.copy() for k, v in self._sig_acc.items()},
        "window": [dataclasses.astuple(e) for e in self._window],
        "sig_window": {k: list(v) for k, v in self._sig_window.items()},
        "update_stats": {k: list(v) for k, v in self._update_stats.items()},
        "recent": (self.recent_picked, self.recent_installed),
    }


def _load_envs_state(self: Any, s: dict[str, Any] | None) -> None:
    if s is None:
        self.obs = None  # saved before any rollout: reset at the first collect
        return
    obs = np.asarray(self.env.restore(s["env"]), np.float32)
    if not np.array_equal(obs, s["obs"]):
        bad = int(np.flatnonzero((obs != s["obs"]).any(axis=1))[0])
        raise ResumeError(
            f"replaying the checkpoint's running episodes does not reproduce env {bad}'s "
            "observation: the simulator is not the one that wrote the checkpoint, so the "
            "run cannot be resumed exactly"
        )
    self.obs = obs
    ep = self.episodes
    ep.ret[:], ep.length[:] = s["episode_ret"], s["episode_length"]
    ep.picked[:], ep.installed[:] = s["episode_picked"], s["episode_installed"]
    self._sig_acc = {k: np.array(v) for k, v in s["sig_acc"].items()}
    self._window = [Episode(*e) for e in s["window"]]
    self._sig_window = {k: list(v) for k, v in s["sig_window"].items()}
    self._update_stats = {k: list(v) for k, v in s["update_stats"].items()}
    self.recent_picked, self.recent_installed = s["recent"]


def load_trainer_state(self: Any, s: dict[str, Any]) -> None:
    self.actor.load_state_dict(s["actor"])
    self.critic.load_state_dict(s["critic"])
    self.opt.load_state_dict(s["opt"])
    if self.gail is not None:
        self.gail.load_state_dict(s["gail"])
    if self.bc is not None:
        self.bc.opt.load_state_dict(s["bc_opt"])
        if s.get("bc_lr") is not None:
            self.bc.current_lr = float(s["bc_lr"])
        else:  # a checkpoint of the older order: the rate its next round would have used
            self.bc.current_lr = bc_learning_rate(
                self.bc.initial_lr, self.bc.steps, int(s["step"]) + self.T * self.N
            )
    if self.curriculum is not None and s.get("curriculum") is not None:
        self.curriculum.load_state_dict(s["curriculum"])
    self.step = int(s["step"])
    self.update_idx = int(s["update_idx"])
    self.last_summary_step = int(s["last_summary_step"])
    self.converged_streak = int(s.get("converged_streak", 0))
    self.rng.bit_generator.state = s["rng"]
    torch.set_rng_state(s["torch_rng"])
    np.random.set_state(s["np_global_rng"])
    random.setstate(s["py_rng"])
    self._steps_at_t = self.step
    if "envs" in s:
        _load_envs_state(self, s["envs"])
    else:
        warnings.warn(
            "checkpoint of an older version (no env state): the envs restart with a seed "
            "derived from the update index, so the resumed run is not exact",
            stacklevel=2,
        )
        self.obs = None
