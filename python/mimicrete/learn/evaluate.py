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

Beside the success rate, every simulator task but Screw reports where the object ended each
episode as a tiler would check it (tile-sim's ``Placement``, read from the vector env in the step
where the episode ended): ``placement`` summarises them (:func:`summarise_placements`, what both
``eval.json`` and :func:`format_placement` show) and each ``per_episode`` record keeps its own.
A success rate says whether the task's own rule was met (the paper's TileSuction: the centre
within 3 cm, held or not, any yaw); the summary's ``placed_share`` says how many of the same
episodes the placed rule of TilePlace would accept, so a policy judged by the paper's rule also
shows how many of its installs a tiler would.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from functools import cache
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch

from mimicrete import _native
from mimicrete._native import MimicreteError

from .env import make_env
from .episodes import EpisodeResult, EpisodeStats, EpisodeTracker
from .networks import Actor, env_action
from .run_files import atomic_write, load_policy
from .starts import StartList, label

__all__ = [
    "eval_file",
    "evaluate_run",
    "format_placement",
    "format_row",
    "format_rows",
    "load_policy",
    "placed_rule",
    "run_episodes",
    "summarise_placements",
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


Placement = dict[str, Any]  # tile-sim's Placement: held, height_above_rest, xy_error, ...


class Finished(NamedTuple):
    """One evaluation episode: where it started and where the object ended (None off the
    simulator; the placement also None for Screw), and what it came to."""

    start: dict[str, Any] | None
    outcome: EpisodeResult
    placement: Placement | None


def _stats(finished: list[Finished], per_episode: bool) -> dict[str, Any]:
    st = EpisodeStats.of([f.outcome for f in finished])
    res: dict[str, Any] = {
        "episodes": st.episodes,
        "picked_rate": st.picked_rate,
        "installed_rate": st.installed_rate,
        "mean_episode_length": st.mean_length,
        "mean_cumulative_reward": st.mean_return,
    }
    placements = [f.placement for f in finished if f.placement is not None]
    if placements:
        res["placement"] = summarise_placements(placements)
    if per_episode:
        res["per_episode"] = [
            {
                **(f.start or {}),
                "picked": f.outcome.picked,
                "installed": f.outcome.installed,
                "length": f.outcome.length,
                **({"placement": f.placement} if f.placement is not None else {}),
            }
            for f in finished
        ]
    return res


@dataclass(frozen=True)
class PlacedRule:
    """The placed rule's tolerances on where an episode left the object (TilePlace's
    ``thresholds``): released (not held), its centre within ``rest_height`` m of the target's
    height, within ``success_dist`` m of it in x and y, its yaw within ``success_yaw_deg``. The
    simulator's rule also asks the tile to have been let go low enough and to be at rest; a
    placement records neither, so this is the rule's check of the end state."""

    rest_height: float
    success_dist: float
    success_yaw_deg: float

    def accepts(self, p: Placement) -> bool:
        return (
            not p["held"]
            and abs(p["height_above_rest"]) <= self.rest_height
            and p["xy_error"] <= self.success_dist
            and abs(p["yaw_error_deg"]) <= self.success_yaw_deg
        )


@cache
def placed_rule() -> PlacedRule:
    """The placed rule's tolerances, read from the built-in TilePlace spec (so they follow it)."""
    th = _native.task_spec("TilePlace")["thresholds"]
    return PlacedRule(
        rest_height=float(th["rest_height"]),
        success_dist=float(th["success_dist"]),
        success_yaw_deg=float(th["success_yaw_deg"]),
    )


#: the placement's signed end-of-episode measures, summarised as median and worst
PLACEMENT_MEASURES = ("height_above_rest", "xy_error", "yaw_error_deg")


def _median_worst(values: Sequence[float]) -> dict[str, float] | None:
    """The median of ``values`` and the worst of them, the one of the largest absolute value
    (its sign kept: a height's worst may be below the rest); None for no values."""
    if not values:
        return None
    a = np.asarray(values, np.float64)
    return {"median": float(np.median(a)), "worst": float(a[np.argmax(np.abs(a))])}


def summarise_placements(placements: Sequence[Placement]) -> dict[str, Any]:
    """What ``eval.json``'s ``placement`` holds and :func:`format_placement` prints, over the
    episodes' placements: the share still held at the end and the share the placed rule
    accepts (:func:`placed_rule`, its tolerances beside it as ``placed_rule``); the height above
    rest, xy error (m) and yaw error (degrees) at the end, and the lip-to-face gap (m) when each
    hold began (over every hold of every episode; None when no episode had a suction hold), each
    as ``{"median", "worst"}``, worst the value of the largest absolute value."""
    if not placements:
        raise ValueError("no placements to summarise")
    rule = placed_rule()
    gaps = [float(g) for p in placements for g in p["hold_gaps"]]
    return {
        "episodes": len(placements),
        "held_share": float(np.mean([bool(p["held"]) for p in placements])),
        "placed_share": float(np.mean([rule.accepts(p) for p in placements])),
        "placed_rule": asdict(rule),
        **{k: _median_worst([float(p[k]) for p in placements]) for k in PLACEMENT_MEASURES},
        "hold_gaps": _median_worst(gaps),
        "holds": len(gaps),
    }


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
    the simulator's tasks) with its ``picked``, ``installed``, ``length`` and ``placement`` (the
    simulator's tasks but Screw), in finishing order. ``placement``: the placements' summary
    (:func:`summarise_placements`), where the episodes have them.
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
    sim = getattr(env, "sim", None)
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
                    results.append(Finished(padded[i], ep, _placement_of(sim, i)))
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
                results.append(Finished(started[i], ep, _placement_of(sim, i)))
                done_count[i] += 1
            started[i] = _start_of(sim, i)  # reset in the same step: its next episode's start
    env.close()
    return results


def _start_of(sim: Any, i: int) -> dict[str, list[float] | float] | None:
    """Where env ``i``'s running episode started, as the eval file holds it (lists of floats; a
    turned pad's ``pad_yaw`` one float)."""
    if sim is None:
        return None
    return {
        k: float(v) if np.isscalar(v) else [float(x) for x in v] for k, v in sim.start(i).items()
    }


def _placement_of(sim: Any, i: int) -> Placement | None:
    """Where env ``i``'s episode that ended in this step left the object (the simulator keeps it
    through the same-step reset); None off the simulator and for Screw."""
    return None if sim is None else sim.last_placement(i)


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


def success_word(env_id: str, task_file: str | None = None) -> str:
    """What a success of ``env_id`` (the spec file ``task_file``'s task) is called: ``placed``
    where its spec judges by the placed rule (TilePlace), else ``installed``."""
    from mimicrete import _native, tasks

    from .env import sim_task_of

    if task_file is not None:
        spec = tasks.load_task_file(task_file)[1]
    else:
        sim = sim_task_of(env_id)
        spec = _native.task_spec(sim) if sim is not None else {}
    return "placed" if spec.get("thresholds", {}).get("rule") == "placed" else "installed"


def percent(share: float) -> str:
    """``share`` as a percentage, to a tenth where a whole number would round it (199 of 200
    is 99.5 %, never "100%")."""
    whole = abs(share * 100 - round(share * 100)) < 1e-9
    return f"{share:.0%}" if whole else f"{share:.1%}"


def format_rows(rows: list[tuple[str, dict]]) -> str:
    """Table 5's columns for each ``(name, result)``, under one header."""
    w = max(24, *(len(n) for n, _ in rows))
    head = f"{'run':<{w}} {'Picked rate':>12} {'Installed rate':>15} {'Average episode length':>23}"
    lines = [head]
    for name, res in rows:
        lines.append(
            f"{name:<{w}} {percent(res['picked_rate']):>12} {percent(res['installed_rate']):>15} "
            f"{res['mean_episode_length']:>23.1f}"
        )
    return "\n".join(lines)


def format_row(name: str, res: dict) -> str:
    return format_rows([(name, res)])


def format_placement(summary: dict[str, Any]) -> str:
    """The placement table of a :func:`summarise_placements` summary (distances in mm)."""
    w = 34
    title = f"placement ({summary['episodes']} episodes)"
    lines = [f"{title:<{w}} {'median':>8} {'worst':>8}  (worst: the largest |value|)"]
    measures = [
        ("height above rest at the end [mm]", "height_above_rest", 1e3),
        ("xy error at the end [mm]", "xy_error", 1e3),
        ("yaw error at the end [deg]", "yaw_error_deg", 1.0),
        ("lip-to-face gap at each hold [mm]", "hold_gaps", 1e3),
    ]
    for name, key, scale in measures:
        mw = summary[key]
        if mw is None:  # hold gaps: grippers, or nothing was ever held
            lines.append(f"{name:<{w}} {'-':>8} {'-':>8}  (no suction holds)")
            continue
        row = f"{name:<{w}} {mw['median'] * scale:>8.1f} {mw['worst'] * scale:>8.1f}"
        lines.append(row + (f"  ({summary['holds']} holds)" if key == "hold_gaps" else ""))
    lines.append(f"{'held at the end':<{w}} {percent(summary['held_share']):>8}")
    rule = summary["placed_rule"]
    tolerances = (
        f"released, |height| <= {rule['rest_height'] * 1e3:g} mm, "
        f"xy <= {rule['success_dist'] * 1e3:g} mm, |yaw| <= {rule['success_yaw_deg']:g} deg"
    )
    lines.append(
        f"{'placed by the placed rule':<{w}} {percent(summary['placed_share']):>8}  ({tolerances})"
    )
    return "\n".join(lines)
