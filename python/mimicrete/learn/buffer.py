"""Rollout storage and generalised advantage estimation.

Arrays are time-major, shape (T, N) for N vectorised envs. For each step t the env returned
``terminated[t]`` / ``truncated[t]``; ``next_values[t]`` is V(s_{t+1}) of the *true* next state: the
next observation in the buffer, the env's ``final_obs`` when the episode ended at t (SAME_STEP
autoreset puts the next episode's first observation in the buffer instead), or the observation
after the last step for the bootstrap at the end of the rollout.

GAE (Schulman et al. 2016) with correct truncation handling:
    delta_t = r_t + gamma * (1 - terminated_t) * next_values_t - values_t
    A_t     = delta_t + gamma * lambda * (1 - cut_t) * A_{t+1}
where ``cut_t`` is true when the trajectory segment ends at t for any reason (termination,
truncation, ML-Agents' ``time_horizon``, end of rollout). A truncated step therefore bootstraps from
V(final_obs), a terminated one does not, and neither leaks advantage across episodes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import torch


def gae(
    rewards: np.ndarray,
    values: np.ndarray,
    next_values: np.ndarray,
    terminated: np.ndarray,
    cut: np.ndarray,
    gamma: float,
    lam: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(advantages, returns), each shaped like ``rewards`` (T, N); returns = advantages + values."""
    T = rewards.shape[0]
    adv = np.zeros_like(rewards, dtype=np.float64)
    not_term = 1.0 - terminated.astype(np.float64)
    not_cut = 1.0 - cut.astype(np.float64)
    last = np.zeros(rewards.shape[1:], dtype=np.float64)
    for t in range(T - 1, -1, -1):
        delta = rewards[t] + gamma * not_term[t] * next_values[t] - values[t]
        last = delta + gamma * lam * not_cut[t] * last
        adv[t] = last
    return adv, adv + values


def horizon_cuts(T: int, N: int, time_horizon: int) -> np.ndarray:
    """Cut mask (T, N) ending a trajectory segment every ``time_horizon`` steps.

    Segments are counted from the start of the rollout (episode ends cut them anyway), and the
    last step of the rollout is always a cut (bootstrapped from the observation after it)."""
    cut = np.zeros((T, N), dtype=bool)
    if time_horizon > 0:
        cut[time_horizon - 1 :: time_horizon] = True
    cut[-1] = True
    return cut


class Rollout:
    """One rollout of T steps x N envs (numpy, preallocated); ``n_branches`` command branches
    (``networks.Actor``)."""

    def __init__(self, T: int, N: int, obs_dim: int, n_cont: int, n_branches: int = 1):
        self.T, self.N = T, N
        self.obs = np.zeros((T, N, obs_dim), np.float32)
        self.u = np.zeros((T, N, n_cont), np.float32)
        self.k = np.zeros((T, N, n_branches), np.int64)
        self.logp = np.zeros((T, N, n_cont + n_branches), np.float32)
        self.env_actions = np.zeros((T, N, n_cont + n_branches), np.float32)
        self.rewards = np.zeros((T, N), np.float32)
        self.terminated = np.zeros((T, N), bool)
        self.truncated = np.zeros((T, N), bool)
        self.final_obs = np.zeros((T, N, obs_dim), np.float32)  # valid where terminated|truncated
        self.last_obs = np.zeros((N, obs_dim), np.float32)

    @property
    def ended(self) -> np.ndarray:
        return self.terminated | self.truncated

    def values_and_next(self, value_fn) -> tuple[np.ndarray, np.ndarray]:
        """(values, next_values), each (T, N, heads): ``value_fn`` ((B, obs_dim) float32 ->
        (B, heads)) of every step's observation and of its true next one (:meth:`next_obs`).
        Most next observations are the buffer's following row, so the critic runs once on the
        distinct ones: the T x N observations, the one after the last step, and the terminal
        observations of the episodes that ended (about half the work of two full passes)."""
        T, N, D = self.obs.shape
        e = self.ended
        rows = np.concatenate([self.obs.reshape(T * N, D), self.last_obs, self.final_obs[e]])
        v = value_fn(rows)
        values = v[: T * N].reshape(T, N, -1)
        nxt = np.empty_like(values)
        nxt[:-1] = values[1:]
        nxt[-1] = v[T * N : T * N + N]
        nxt[e] = v[T * N + N :]
        return values, nxt

    def next_obs(self) -> np.ndarray:
        """(T, N, obs_dim): the true next observation of every step."""
        nxt = np.empty_like(self.obs)
        nxt[:-1] = self.obs[1:]
        nxt[-1] = self.last_obs
        e = self.ended
        nxt[e] = self.final_obs[e]
        return nxt


@dataclass
class Signal:
    """One reward signal over the rollout: strength-scaled rewards (T, N), its gamma and the
    termination mask its GAE uses."""

    name: str
    rewards: np.ndarray
    gamma: float
    terminated: np.ndarray


@dataclass
class UpdateBuffer:
    """The rollout flattened to T * N rows, with advantages and returns."""

    obs: np.ndarray
    u: np.ndarray
    k: np.ndarray  # (T * N, n_branches)
    logp: np.ndarray  # (T * N, n_cont + n_branches)
    env_actions: np.ndarray
    adv: np.ndarray
    values: np.ndarray  # (T * N, n_signals), at collection time
    returns: np.ndarray  # (T * N, n_signals)

    def tensors(self) -> dict[str, torch.Tensor]:
        import torch

        return {k: torch.from_numpy(v) for k, v in self.__dict__.items()}
