"""Episode statistics, the same for training and evaluation: per env, the return, the length and
whether the tile was picked / installed; and the means over a set of finished episodes (Table 5's
picked rate, installed rate and average episode length).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class EpisodeResult:
    """What one finished episode came to: its return, its length in steps, and whether the tile
    was picked and installed in it."""

    ret: float
    length: int
    picked: bool
    installed: bool


def episode_flags(
    infos: dict, rewards: np.ndarray, terminated: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(picked_now, installed_now) per env at this step: the env's flags if it reports them,
    else from the reward (pick: +1 while not terminal; install: terminal with reward > 0)."""
    if "picked" in infos and "installed" in infos:
        return np.asarray(infos["picked"], bool), np.asarray(infos["installed"], bool)
    picked = rewards > 0.5
    installed = terminated & (rewards > 0.5)
    return picked, installed


class EpisodeTracker:
    """Running return, length and picked / installed flags of each of ``n`` envs' episodes."""

    def __init__(self, n: int):
        self.n = n
        self.reset()

    def reset(self) -> None:
        """Forget every running episode (after the envs were reset)."""
        self.ret = np.zeros(self.n)
        self.length = np.zeros(self.n, np.int64)
        self.picked = np.zeros(self.n, bool)
        self.installed = np.zeros(self.n, bool)

    def step(
        self, infos: dict, rewards: np.ndarray, terminated: np.ndarray, truncated: np.ndarray
    ) -> list[tuple[int, EpisodeResult]]:
        """Account one vector-env step; returns the episodes that ended in it as (env index,
        episode), in env order, and starts those envs' next episodes."""
        picked, installed = episode_flags(infos, rewards, terminated)
        self.ret += rewards
        self.length += 1
        self.picked |= picked
        self.installed |= installed
        ended = terminated | truncated
        done = [
            (
                int(i),
                EpisodeResult(
                    float(self.ret[i]),
                    int(self.length[i]),
                    bool(self.picked[i]),
                    bool(self.installed[i]),
                ),
            )
            for i in np.flatnonzero(ended)
        ]
        if done:
            self.ret[ended] = 0.0
            self.length[ended] = 0
            self.picked[ended] = False
            self.installed[ended] = False
        return done


@dataclass(frozen=True)
class EpisodeStats:
    """Means over finished episodes."""

    episodes: int
    mean_return: float
    mean_length: float
    picked_rate: float
    installed_rate: float

    @classmethod
    def of(cls, episodes: Sequence[EpisodeResult]) -> EpisodeStats:
        if not episodes:
            raise ValueError("no finished episodes")
        return cls(
            episodes=len(episodes),
            mean_return=float(np.mean([e.ret for e in episodes])),
            mean_length=float(np.mean([e.length for e in episodes])),
            picked_rate=float(np.mean([e.picked for e in episodes])),
            installed_rate=float(np.mean([e.installed for e in episodes])),
        )
