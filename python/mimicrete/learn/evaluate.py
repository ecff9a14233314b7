"""Evaluation of a trained run: the paper's Table 5 row (picked rate, installed rate, average
episode length).

The deterministic policy (Gaussian mean clipped to [-1, 1], most likely end-effector command) runs
on fresh envs (seed = the run's seed + 10,000 unless given). With ``stochastic`` the policy is
sampled instead, as ML-Agents runs a trained model unless ``deterministic_inference`` is set (the
paper does not say which it used); the samples are drawn from a torch generator seeded with the
eval seed, so a stochastic evaluation is reproducible too. It is written to
``eval_stochastic.json`` beside the deterministic ``eval.json``. With ``robust`` the episodes start
wider than in training (tile-sim's ``Variation::robust``: the tile's x range widened by half on
each side, [-0.075, 0.225] m, and the target moved by up to ±2 cm in x and y), written to
``eval_robust.json`` (``eval_robust_stochastic.json``). To avoid favouring short episodes,
``episodes`` is split evenly over the envs and each env contributes exactly its first
``episodes / num_envs`` episodes. ``evaluate_run`` writes ``eval.json`` into the run dir.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import torch

from .env import make_env
from .episodes import Episode, EpisodeStats, EpisodeTracker
from .networks import Actor, env_action
from .run_files import load_policy

__all__ = ["eval_file", "evaluate_run", "format_row", "load_policy", "run_episodes"]


def _num_envs_for(episodes: int, cap: int = 32) -> int:
    return max(d for d in range(1, min(cap, episodes) + 1) if episodes % d == 0)


def eval_file(stochastic: bool, robust: bool = False) -> str:
    """The file an evaluation writes into the run dir."""
    return "eval" + ("_robust" if robust else "") + ("_stochastic" if stochastic else "") + ".json"


@torch.no_grad()
def run_episodes(
    actor: Actor,
    env_id: str,
    episodes: int,
    seed: int,
    max_envs: int = 32,
    stochastic: bool = False,
    robust: bool = False,
) -> dict[str, float]:
    """Mean statistics of ``episodes`` episodes of ``actor``, deterministic or sampled, from the
    training's starts or the robust ones."""
    if episodes < 1:
        raise ValueError(f"episodes: at least 1, got {episodes}")
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        return _run_episodes(actor, env_id, episodes, seed, max_envs, stochastic, robust)


def _run_episodes(
    actor: Actor,
    env_id: str,
    episodes: int,
    seed: int,
    max_envs: int,
    stochastic: bool,
    robust: bool,
) -> dict[str, float]:
    n = _num_envs_for(episodes, max_envs)
    per_env = episodes // n
    env = make_env(env_id, n, seed)
    if robust:
        sim = getattr(env, "sim", None)
        if sim is None:
            env.close()
            raise ValueError(f"a robust evaluation needs the simulator's env, not {env_id}")
        sim.set_variation(robust=True)
    obs, _ = env.reset(seed=seed)
    obs = np.asarray(obs, np.float32)
    tracker = EpisodeTracker(n)
    done_count = np.zeros(n, np.int64)
    results: list[Episode] = []
    while (done_count < per_env).any():
        o = torch.from_numpy(obs)
        if stochastic:
            u, k, _ = actor.sample(o)
            act = env_action(u, k).numpy()
        else:
            act = actor.deterministic(o).numpy()
        obs, r, term, trunc, infos = env.step(act)
        obs = np.asarray(obs, np.float32)
        r = np.asarray(r, np.float32)
        for i, ep in tracker.step(infos, r, np.asarray(term, bool), np.asarray(trunc, bool)):
            if done_count[i] < per_env:
                results.append(ep)
                done_count[i] += 1
    env.close()
    st = EpisodeStats.of(results)
    return {
        "episodes": st.episodes,
        "picked_rate": st.picked_rate,
        "installed_rate": st.installed_rate,
        "mean_episode_length": st.mean_length,
        "mean_cumulative_reward": st.mean_return,
    }


def evaluate_run(
    run_dir: str | Path,
    episodes: int,
    seed: int | None = None,
    stochastic: bool = False,
    robust: bool = False,
) -> dict[str, Any]:
    """Evaluate ``run_dir/policy.pt`` on ``episodes`` episodes; writes and returns ``eval.json``
    (or :func:`eval_file`'s name for ``stochastic`` / ``robust``)."""
    run_dir = Path(run_dir)
    if episodes < 1:
        raise ValueError(f"episodes: at least 1, got {episodes}")
    actor, cfg = load_policy(run_dir)
    s = cfg.env_settings.seed + 10_000 if seed is None else seed
    env_id = cfg.env_settings.env_id
    res = run_episodes(actor, env_id, episodes, s, stochastic=stochastic, robust=robust)
    res = {
        **res,
        "seed": s,
        "env_id": env_id,
        "policy": "stochastic" if stochastic else "deterministic",
        "starts": "robust" if robust else "training",
    }
    (run_dir / eval_file(stochastic, robust)).write_text(json.dumps(res, indent=1))
    return res


def format_row(name: str, res: dict) -> str:
    head = f"{'run':<24} {'Picked rate':>12} {'Installed rate':>15} {'Average episode length':>23}"
    row = (
        f"{name:<24} {res['picked_rate']:>12.0%} {res['installed_rate']:>15.0%} "
        f"{res['mean_episode_length']:>23.1f}"
    )
    return f"{head}\n{row}"
