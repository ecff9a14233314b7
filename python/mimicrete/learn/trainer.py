"""A training run's trainer: what stays fixed during the run (the config, the demos, the sizes,
the run dir) and the :class:`~run_state.RunState` that every update changes (:attr:`Trainer.state`;
``checkpoint.py`` saves and restores exactly that).

One update, rollout -> reward signals -> GAIL's discriminator -> GAE -> PPO -> BC, is
``update.py``, read top to bottom (:meth:`Trainer.iterate` runs it). Around it, here: the offline
BC warm start (:meth:`~Trainer.pretrain`), the summary rows (:meth:`~Trainer.summary`) and the
checkpoints. The run around the trainer (run dir, resume, when to summarise and checkpoint, the
scalar log) is ``loop.py``.

``--resume`` is exact (bit for bit: weights, optimisers, scalars) and checkpoints do not change
training: the envs are reset once, at the start, with a seed derived from the run's seed, and a
checkpoint (always at an update boundary) stores the vector env's ``state()``: its base seed, each
env's episode count (the simulator derives every auto-reset's seed from (base, env index, episode
count)) and the actions of each running episode. Resuming replays those actions (the simulator is
deterministic) and checks that the replay reproduces the stored observations; the per-env running
returns and the scalars not yet summarised are stored with it.
"""

from __future__ import annotations

import math
import random
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import torch

from . import checkpoint, run_files
from . import config as config_mod
from .demo_data import TrainingDemos, read_training_demos
from .env import N_CONT, command_branches, make_env
from .episodes import EpisodeStats
from .run_state import RunState, new_run_state
from .update import SIGNAL_TAG, NonFiniteLossError, one_update

__all__ = ["NonFiniteLossError", "Trainer"]


class Trainer:
    """One training run's fixed setup (config, demos, sizes) and its
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
        self.run_dir = Path(run_dir)
        self.max_steps = max_steps
        self.seed = cfg.env_settings.seed
        threads = max(1, cfg.torch_settings.num_threads)
        torch.set_num_threads(threads)
        random.seed(self.seed)
        np.random.seed(self.seed % 2**32)
        torch.manual_seed(self.seed)

        es = cfg.env_settings
        env = make_env(es.env_id, es.num_envs, self.seed, es.task_file)
        self.obs_dim = int(env.single_observation_space.shape[0])
        self.n_branches = command_branches(env)  # 1 (end effector), Screw 2 (+ spin)
        b = self.behavior
        self.demos: TrainingDemos | None = None
        wants_demos = (b.reward_signals.gail, b.behavioral_cloning, b.demo_curriculum)
        if any(x is not None for x in wants_demos):  # read once, for all three
            self.demos = read_training_demos(
                demos_override or cfg.demo_path, b.demo_episodes, b.demo_drop_idle,
                es.env_id, N_CONT + self.n_branches, skip_bad=skip_bad_demos,
                task_file=es.task_file,
            )  # fmt: skip
        self.state: RunState = new_run_state(
            cfg, env, self.obs_dim, self.n_branches, self.demos, self.seed
        )
        # GAIL's discriminator steps on a thread of their own (update.py, step 4); the thread
        # gets the same torch thread count (OpenMP's is per thread)
        self.gail_thread: ThreadPoolExecutor | None = None
        if self.state.gail is not None and cfg.torch_settings.overlap_gail:
            self.gail_thread = ThreadPoolExecutor(
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
        if losses and not math.isfinite(losses[-1]):
            raise NonFiniteLossError(self._stopped(f"the BC warm-start loss is {losses[-1]}"))
        st.pending.log("Losses/Pretraining Loss", float(np.mean(losses[-50:])))
        return {
            "grad_steps": steps,
            "passes": round(steps / per_pass, 2),
            "demo_steps": int(st.bc.obs.shape[0]),
        }

    def iterate(self) -> None:
        """One update (``update.one_update``): rollout -> reward signals -> GAIL's discriminator
        -> GAE -> PPO -> BC."""
        try:
            one_update(self.state, self.behavior, self.max_steps, self.seed, self.gail_thread)
        except NonFiniteLossError as e:  # say also where training stopped and what is kept
            raise NonFiniteLossError(self._stopped(str(e))) from None

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

    def close(self) -> None:
        """Release the envs and the GAIL thread once training is over (the trainer's weights,
        normalisers and state stay readable)."""
        self.state.env.close()
        if self.gail_thread is not None:
            self.gail_thread.shutdown(wait=True)
            self.gail_thread = None

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
                    raise NonFiniteLossError(self._stopped(f"weight {name} is not finite"))
        return run_files.save_checkpoint(
            self.run_dir, self.state.step, self.state_dict(), self.behavior.keep_checkpoints
        )

    def _stopped(self, what: str) -> str:
        """The message of a :class:`NonFiniteLossError`: ``what`` is not finite, where, and
        which checkpoint is kept."""
        ck = run_files.latest_checkpoint(self.run_dir)
        kept = f"the last good checkpoint is {ck}" if ck else "no checkpoint was written yet"
        return (
            f"{what} at step {self.state.step} (update {self.state.update_idx}); training "
            f"stopped, {kept} (a smaller learning rate or strength may help)"
        )
