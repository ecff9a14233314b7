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
``eval_robust.json`` (``eval_robust_stochastic.json``). ``starts`` names any of the start sets of
:mod:`mimicrete.learn.starts` (``training``, ``robust``, ``wide``: written to ``eval_wide.json``)
or gives a :class:`~mimicrete.learn.starts.StartList` read from a file (one episode per start,
``eval_starts-<file stem>.json``). To avoid favouring short episodes, ``episodes`` is split
evenly over the envs and each env contributes exactly its first ``episodes / num_envs``
episodes. ``evaluate_run`` writes ``eval.json`` into the run dir; every result says which
starts it used.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import torch

from mimicrete._native import MimicreteError

from .env import make_env
from .episodes import EpisodeResult, EpisodeStats, EpisodeTracker
from .networks import Actor, env_action
from .run_files import atomic_write, load_policy
from .starts import StartList, label

__all__ = [
    "eval_file",
    "evaluate_run",
    "format_row",
    "format_rows",
    "load_policy",
    "run_episodes",
]


def _num_envs_for(episodes: int, cap: int = 32) -> int:
    return max(d for d in range(1, min(cap, episodes) + 1) if episodes % d == 0)


def eval_file(stochastic: bool, robust: bool = False, starts: str | StartList = "training") -> str:
    """The file an evaluation writes into the run dir."""
    if robust:
        starts = "robust"
    if isinstance(starts, StartList):
        part = f"_starts-{starts.path.stem}"
    else:
        part = "" if starts == "training" else f"_{starts}"
    return "eval" + part + ("_stochastic" if stochastic else "") + ".json"


def _policy_action(actor: Actor, obs: np.ndarray, stochastic: bool) -> np.ndarray:
    o = torch.from_numpy(obs)
    if stochastic:
        u, k, _ = actor.sample(o)
        return env_action(u, k).numpy()
    return actor.deterministic(o).numpy()


Finished = tuple[dict[str, Any] | None, EpisodeResult]  # (where it started, what it came to)


def _stats(finished: list[Finished], per_episode: bool) -> dict[str, Any]:
    st = EpisodeStats.of([ep for _, ep in finished])
    res: dict[str, Any] = {
        "episodes": st.episodes,
        "picked_rate": st.picked_rate,
        "installed_rate": st.installed_rate,
        "mean_episode_length": st.mean_length,
        "mean_cumulative_reward": st.mean_return,
    }
    if per_episode:
        res["per_episode"] = [
            {**(start or {}), "picked": ep.picked, "installed": ep.installed, "length": ep.length}
            for start, ep in finished
        ]
    return res


@torch.no_grad()
def run_episodes(
    actor: Actor,
    env_id: str,
    episodes: int,
    seed: int,
    max_envs: int = 32,
    stochastic: bool = False,
    robust: bool = False,
    starts: str | StartList = "training",
    per_episode: bool = False,
    task_file: str | None = None,
) -> dict[str, Any]:
    """Mean statistics of ``episodes`` episodes of ``actor``, deterministic or sampled, from the
    named ``starts`` (``robust=True`` is ``starts="robust"``) or, for a :class:`StartList`, one
    episode from each of its starts (``episodes`` is then ignored). With ``per_episode``, also
    ``per_episode``: each episode's start (``object_pose``, ``target_offset``, ``pad_offset``;
    the simulator's tasks) with its ``picked``, ``installed`` and ``length``, in finishing order.
    ``task_file``: the task spec file a ``Task-v0`` policy runs in."""
    if episodes < 1:
        raise ValueError(f"episodes: at least 1, got {episodes}")
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        if isinstance(starts, StartList):
            n = min(max_envs, len(starts.starts))
        else:
            n = _num_envs_for(episodes, max_envs)
        env = make_env(env_id, n, seed, task_file)
        _check_obs_dim(actor, env, env_id)
        if isinstance(starts, StartList):
            done = _run_listed(actor, env, starts, seed, stochastic)
        else:
            name = "robust" if robust else starts
            done = _run_episodes(actor, env, env_id, episodes, seed, stochastic, name)
    return _stats(done, per_episode)


class ObsDimError(MimicreteError, ValueError):
    """A policy that reads observations of another size than its env gives."""


def _check_obs_dim(actor: Actor, env: Any, env_id: str) -> None:
    """:class:`ObsDimError` when ``actor`` reads observations of another size than ``env`` gives
    (a policy trained before the task's observation changed)."""
    want = int(actor.norm.mean.shape[0])
    got = int(env.single_observation_space.shape[0])
    if want != got:
        raise ObsDimError(
            f"the policy reads {want}-float observations, {env_id} gives {got} "
            "(trained with an older observation layout of the task: train it again)"
        )


def _run_listed(
    actor: Actor, env: Any, starts: StartList, seed: int, stochastic: bool
) -> list[Finished]:
    """One episode from each listed start, in batches of ``env``'s envs (a batch's spare envs
    repeat its first start and are not counted)."""
    todo = list(starts.starts)
    n = int(env.num_envs)
    results: list[Finished] = []
    for b in range(0, len(todo), n):
        batch = todo[b : b + n]
        padded = batch + [batch[0]] * (n - len(batch))
        options = {
            "object_pose": [st["object_pose"] for st in padded],
            "target_offset": [st.get("target_offset", [0.0, 0.0]) for st in padded],
        }
        obs, _ = env.reset(seed=seed + b, options=options)
        obs = np.asarray(obs, np.float32)
        tracker = EpisodeTracker(n)
        done = np.zeros(n, bool)
        done[len(batch) :] = True
        while not done.all():
            obs, r, term, trunc, infos = env.step(_policy_action(actor, obs, stochastic))
            obs = np.asarray(obs, np.float32)
            r = np.asarray(r, np.float32)
            for i, ep in tracker.step(infos, r, np.asarray(term, bool), np.asarray(trunc, bool)):
                if not done[i]:
                    results.append((padded[i], ep))
                    done[i] = True
    env.close()
    return results


def _run_episodes(
    actor: Actor,
    env: Any,
    env_id: str,
    episodes: int,
    seed: int,
    stochastic: bool,
    starts: str,
) -> list[Finished]:
    n = int(env.num_envs)
    per_env = episodes // n
    if starts != "training":
        sim = getattr(env, "sim", None)
        if sim is None:
            env.close()
            raise ValueError(f"starts {starts!r} need the simulator's env, not {env_id}")
        sim.set_variation(starts=starts)
    obs, _ = env.reset(seed=seed)
    obs = np.asarray(obs, np.float32)
    sim = getattr(env, "sim", None)
    started = [_start_of(sim, i) for i in range(n)]
    tracker = EpisodeTracker(n)
    done_count = np.zeros(n, np.int64)
    results: list[Finished] = []
    while (done_count < per_env).any():
        obs, r, term, trunc, infos = env.step(_policy_action(actor, obs, stochastic))
        obs = np.asarray(obs, np.float32)
        r = np.asarray(r, np.float32)
        for i, ep in tracker.step(infos, r, np.asarray(term, bool), np.asarray(trunc, bool)):
            if done_count[i] < per_env:
                results.append((started[i], ep))
                done_count[i] += 1
            started[i] = _start_of(sim, i)  # reset in the same step: its next episode's start
    env.close()
    return results


def _start_of(sim: Any, i: int) -> dict[str, list[float]] | None:
    """Where env ``i``'s running episode started, as the eval file holds it (lists of floats)."""
    if sim is None:
        return None
    return {k: [float(x) for x in v] for k, v in sim.start(i).items()}


def evaluate_run(
    run_dir: str | Path,
    episodes: int,
    seed: int | None = None,
    stochastic: bool = False,
    robust: bool = False,
    starts: str | StartList = "training",
) -> dict[str, Any]:
    """Evaluate ``run_dir/policy.pt`` on ``episodes`` episodes; writes and returns ``eval.json``
    (or :func:`eval_file`'s name for ``stochastic`` / ``robust`` / ``starts``), each episode's
    start and outcome under ``per_episode`` (what :func:`.plots.success_map` draws)."""
    run_dir = Path(run_dir)
    if episodes < 1:
        raise ValueError(f"episodes: at least 1, got {episodes}")
    actor, cfg = load_policy(run_dir)
    s = cfg.env_settings.seed + 10_000 if seed is None else seed
    env_id = cfg.env_settings.env_id
    if robust:
        starts = "robust"
    task_file = cfg.env_settings.task_file
    try:
        res = run_episodes(
            actor, env_id, episodes, s, stochastic=stochastic, starts=starts, per_episode=True,
            task_file=task_file,
        )  # fmt: skip
    except ObsDimError as e:
        raise ObsDimError(f"{run_dir / 'policy.pt'}: {e}") from None
    res = {
        **res,
        "seed": s,
        "env_id": env_id,
        **({"task_file": task_file} if task_file else {}),
        "policy": "stochastic" if stochastic else "deterministic",
        "starts": label(starts),
    }
    if isinstance(starts, StartList):
        res["starts_sha256"] = starts.sha256
    atomic_write(run_dir / eval_file(stochastic, starts=starts), json.dumps(res, indent=1))
    return res


def format_rows(rows: list[tuple[str, dict]]) -> str:
    """Table 5's columns for each ``(name, result)``, under one header."""
    w = max(24, *(len(n) for n, _ in rows))
    head = f"{'run':<{w}} {'Picked rate':>12} {'Installed rate':>15} {'Average episode length':>23}"
    lines = [head]
    for name, res in rows:
        lines.append(
            f"{name:<{w}} {res['picked_rate']:>12.0%} {res['installed_rate']:>15.0%} "
            f"{res['mean_episode_length']:>23.1f}"
        )
    return "\n".join(lines)


def format_row(name: str, res: dict) -> str:
    return format_rows([(name, res)])
