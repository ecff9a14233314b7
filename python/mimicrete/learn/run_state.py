"""Everything a training run changes as it goes, in one typed place: :class:`RunState`.

One update (``update.py``) reads and changes it; ``checkpoint.py`` saves it and puts it back
(``--resume``). What stays fixed during a run (the config, the demos, the run dir) is not in it.
Besides what is here, a checkpoint holds the process's global random streams (torch, numpy's and
Python's), which the networks' sampling and initialisation draw from.

:func:`new_run_state` builds the state of a fresh run from its config: the networks, their
optimisers, the reward signals, BC and the curriculum, in the order that fixes their random
initialisation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from . import config as config_mod
from .bc import BehavioralCloning
from .buffer import Rollout
from .curriculum import ReverseCurriculum, demo_tracks
from .demo_data import TrainingDemos
from .env import N_CONT
from .episodes import EpisodeResult, EpisodeTracker
from .gail import Gail
from .networks import Actor, Critic


@dataclass
class Pending:
    """What the next summary row averages (gathered since the last one)."""

    episodes: list[EpisodeResult] = field(default_factory=list)  # ended, from the env's own starts
    signal_returns: dict[str, list[float]] = field(default_factory=dict)  # per signal, episode sums
    update_stats: dict[str, list[float]] = field(default_factory=dict)  # per scalar key, values

    def log(self, key: str, value: float) -> None:
        self.update_stats.setdefault(key, []).append(float(value))

    def clear(self) -> None:
        self.episodes.clear()
        for v in self.signal_returns.values():
            v.clear()
        self.update_stats.clear()


@dataclass
class RunState:
    """The networks, optimisers, envs, buffers, counters and the run's own random stream."""

    # -- what learns --------------------------------------------------------------------------
    actor: Actor
    critic: Critic  # one value head per reward signal
    opt: torch.optim.Adam  # PPO's, over actor + critic
    gail: Gail | None  # the discriminator, its optimiser and the expert inputs
    bc: BehavioralCloning | None  # BC's own optimiser over the actor, its rate
    curriculum: ReverseCurriculum | None  # the demo starts and where each env's episode began
    signals: list[str]  # the reward signals, in value-head order: "extrinsic", "gail"

    # -- the envs and what outlives a rollout -------------------------------------------------
    env: Any  # the vector env (``env.make_env``)
    rollout: Rollout  # T steps x N envs, refilled every update
    episodes: EpisodeTracker  # each env's running episode: return, length, picked, installed
    signal_sums: dict[str, np.ndarray]  # each env's running episode sum of each signal
    rng: np.random.Generator  # the run's own stream: minibatches, GAIL's expert rows, BC
    obs: np.ndarray | None = None  # each env's current observation (None: not reset yet)

    # -- counters -----------------------------------------------------------------------------
    step: int = 0  # env steps so far (N per vector step)
    update_idx: int = 0  # updates done
    last_summary_step: int = 0
    converged_streak: int = 0  # summaries in a row that met stop_on_convergence

    # -- the log ------------------------------------------------------------------------------
    pending: Pending = field(default_factory=Pending)
    recent_picked: float = 0.0  # the last summary's rates (the progress bar shows them)
    recent_installed: float = 0.0

    @property
    def steps_per_update(self) -> int:
        return self.rollout.T * self.rollout.N

    def networks(self) -> dict[str, torch.nn.Module]:
        """The networks whose weights must stay finite, by name."""
        nets: dict[str, torch.nn.Module] = {"actor": self.actor, "critic": self.critic}
        if self.gail is not None:
            nets["discriminator"] = self.gail.disc
        return nets

    def reset_signal_sums(self) -> None:
        n = self.rollout.N
        self.signal_sums = {s: np.zeros(n) for s in self.signals}


def disc_inputs(
    gail: config_mod.GailSettings | None, obs: np.ndarray, actions: np.ndarray
) -> np.ndarray:
    """What the discriminator reads: the observation, and the env action with ``use_actions``."""
    if gail is not None and gail.use_actions:
        return np.concatenate([obs, actions], -1).astype(np.float32)
    return np.asarray(obs, np.float32)


def new_run_state(
    cfg: config_mod.TrainerConfig,
    env: Any,
    obs_dim: int,
    n_branches: int,
    demos: TrainingDemos | None,
    seed: int,
) -> RunState:
    """A fresh run's state: networks initialised from torch's stream (seeded by the caller),
    nothing collected yet."""
    b = cfg.behavior
    hp = b.hyperparameters
    rs = b.reward_signals
    given = (("extrinsic", rs.extrinsic), ("gail", rs.gail))
    signals = [name for name, s in given if s is not None]
    ns = b.network_settings
    actor = Actor(obs_dim, N_CONT, ns.hidden_units, ns.num_layers, ns.normalize, n_branches,
                  b.init_std)  # fmt: skip
    critic = Critic(obs_dim, len(signals), ns.hidden_units, ns.num_layers, ns.normalize)
    opt = torch.optim.Adam(
        list(actor.parameters()) + list(critic.parameters()), lr=hp.learning_rate
    )
    gail = None
    if rs.gail is not None:
        assert demos is not None
        g = rs.gail
        gail = Gail(
            disc_inputs(g, demos.arrays["obs"], demos.arrays["actions"]),
            g.network_settings.hidden_units,
            g.network_settings.num_layers,
            g.learning_rate,
            normalize=g.network_settings.normalize,
        )
    bc = None
    bcs = b.behavioral_cloning
    if bcs is not None:
        assert demos is not None
        bc = BehavioralCloning(
            actor,
            demos.arrays["obs"],
            demos.arrays["actions"],
            initial_lr=hp.learning_rate * bcs.strength,
            steps=bcs.steps,
            batch_size=bcs.batch_size or hp.batch_size,
            num_epoch=bcs.num_epoch or hp.num_epoch,
            samples_per_update=bcs.samples_per_update,
            ee_class_balance=bcs.ee_class_balance,
        )
    n = cfg.env_settings.num_envs
    curriculum = None
    if b.demo_curriculum is not None:
        assert demos is not None
        if not hasattr(env, "reset_replay"):
            raise config_mod.ConfigError(
                f"demo_curriculum: {cfg.env_settings.env_id} cannot replay demos"
            )
        tracks = demo_tracks(demos.loaded)
        curriculum = ReverseCurriculum(
            tracks[: b.demo_curriculum.max_demos],
            b.demo_curriculum,
            n,
            np.random.default_rng(seed + 1),
        )
    return RunState(
        actor=actor,
        critic=critic,
        opt=opt,
        gail=gail,
        bc=bc,
        curriculum=curriculum,
        signals=signals,
        env=env,
        rollout=Rollout(hp.buffer_size // n, n, obs_dim, N_CONT, n_branches),
        episodes=EpisodeTracker(n),
        signal_sums={s: np.zeros(n) for s in signals},
        rng=np.random.default_rng(seed),
        pending=Pending(signal_returns={s: [] for s in signals}),
    )
