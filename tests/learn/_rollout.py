"""An evaluation's episode counted by hand: the run's deterministic policy stepped in one env
until the episode ends, independently of :mod:`mimicrete.learn.evaluate`'s episode tracker."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from mimicrete.learn.env import make_env
from mimicrete.learn.run_files import load_policy


@torch.no_grad()
def first_episode(run_dir: str | Path, seed: int) -> tuple[int, float, bool]:
    """(steps, return, truncated) of the first episode of ``run_dir``'s deterministic policy in
    one env seeded ``seed``: what ``evaluate_run(run_dir, 1, seed=seed)`` must report."""
    actor, cfg = load_policy(Path(run_dir))
    env = make_env(cfg.env_settings.env_id, 1, seed)
    try:
        obs, _ = env.reset(seed=seed)
        steps, ret = 0, 0.0
        while True:
            act = actor.deterministic(torch.from_numpy(np.asarray(obs, np.float32))).numpy()
            obs, r, term, trunc, _ = env.step(act)
            steps, ret = steps + 1, ret + float(np.asarray(r)[0])
            if bool(np.asarray(term)[0]) or bool(np.asarray(trunc)[0]):
                return steps, ret, bool(np.asarray(trunc)[0])
    finally:
        env.close()


def evaluated_first_episode(run_dir: str | Path, seed: int) -> dict[str, float]:
    """What the evaluation reports for that one episode (``run_episodes``: no file written)."""
    from mimicrete.learn.evaluate import run_episodes

    actor, cfg = load_policy(Path(run_dir))
    return run_episodes(actor, cfg.env_settings.env_id, 1, seed)
