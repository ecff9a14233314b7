"""The numbers the report states: per-group means and standard deviations over seeds, steps to
97 % installed, the GAIL loss over the last 100k steps, confidence bands of learning curves, and
the rule for "agrees with the paper"."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .sweep_runs import Run

TAG_REWARD = "Environment/Cumulative Reward"
TAG_INSTALLED = "Environment/Installed Rate"
TAG_EPISODES = "Environment/Episodes"
MIN_EPISODES = 20  # finished episodes a rate summary needs to count for steps-to-97 %
TAG_PICKED = "Environment/Picked Rate"
TAG_GAIL_LOSS = "Losses/GAIL Loss"

# Agreement rule for the generated comparison text.
RATE_TOL = 0.10  # absolute, or 2 standard errors of the seed mean if larger
LENGTH_TOL = 0.20  # relative to the paper's length, or 2 standard errors if larger
GAIL_WINDOW = 100_000  # §5.2 averages the GAIL loss over the last 100,000 steps
THRESHOLD = 0.97  # Table 5's best installed rate; steps-to-threshold uses it


def mean_sd(values: list[float]) -> tuple[float, float, int]:
    """(mean, sample standard deviation (0 for one value), n); NaNs for no values."""
    x = np.asarray([v for v in values if v is not None and math.isfinite(v)], np.float64)
    if len(x) == 0:
        return math.nan, math.nan, 0
    sd = float(np.std(x, ddof=1)) if len(x) > 1 else 0.0
    return float(np.mean(x)), sd, len(x)


def steps_to_threshold(steps: np.ndarray, values: np.ndarray, threshold: float) -> int | None:
    """First logged step whose value is >= ``threshold`` (None if never)."""
    hit = np.flatnonzero(np.asarray(values) >= threshold)
    return int(np.asarray(steps)[hit[0]]) if len(hit) else None


def last_window_mean(steps: np.ndarray, values: np.ndarray, window: int) -> float:
    """Mean of the values logged in the last ``window`` steps (step > last - window)."""
    steps = np.asarray(steps)
    if len(steps) == 0:
        return math.nan
    keep = steps > steps[-1] - window
    return float(np.mean(np.asarray(values)[keep]))


def curve_band(
    curves: list[tuple[np.ndarray, np.ndarray]], points: int = 200, level: float = 0.95
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Seeds' curves on a common step grid (linear interpolation inside each curve's range):
    (grid, mean, lower, upper) with a Student-t confidence band of the mean over the seeds that
    cover a grid point (no band where only one does)."""
    from scipy import stats

    curves = [(np.asarray(s, float), np.asarray(v, float)) for s, v in curves if len(s)]
    if not curves:
        e = np.zeros(0)
        return e, e, e, e
    lo_s = min(s[0] for s, _ in curves)
    hi_s = max(s[-1] for s, _ in curves)
    grid = np.linspace(lo_s, hi_s, points) if hi_s > lo_s else np.array([lo_s])
    ys = np.full((len(curves), len(grid)), np.nan)
    for i, (s, v) in enumerate(curves):
        inside = (grid >= s[0]) & (grid <= s[-1])
        ys[i, inside] = np.interp(grid[inside], s, v)
    n = np.sum(~np.isnan(ys), axis=0)
    with warnings.catch_warnings():  # all-NaN columns (no seed covers the point) give NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        mean = np.nanmean(ys, axis=0)
        sd = np.nanstd(ys, axis=0, ddof=1) if len(curves) > 1 else np.zeros(len(grid))
    sd = np.where(n > 1, sd, 0.0)
    t = np.where(n > 1, stats.t.ppf(0.5 + level / 2, np.maximum(n - 1, 1)), 0.0)
    half = t * sd / np.sqrt(np.maximum(n, 1))
    return grid, mean, mean - half, mean + half


def held_to_budget(
    steps: np.ndarray, values: np.ndarray, converged_at: int | None, budget: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """A curve of a run that stopped on convergence, its last summary held to the step budget
    (its policy is final: it would have trained no further), so a seed mean over the budget
    stays a mean over every seed. Other curves are returned as they are."""
    if converged_at is None or budget is None or not len(steps) or steps[-1] >= budget:
        return steps, values
    return np.append(steps, budget), np.append(values, values[-1])


@dataclass
class GroupStats:
    group: int
    runs: list[Run]
    picked: tuple[float, float, int]
    installed: tuple[float, float, int]
    length: tuple[float, float, int]
    gail_loss: tuple[float, float, int]
    steps_to: list[int | None]
    final_installed_train: tuple[float, float, int]
    trend: float  # installed rate: mean of the last 10 % of steps minus the 10 % before
    # the same evaluation with the policy sampled (ML-Agents' inference unless
    # deterministic_inference is set; the paper does not say which it used)
    picked_sampled: tuple[float, float, int] = (math.nan, math.nan, 0)
    installed_sampled: tuple[float, float, int] = (math.nan, math.nan, 0)
    length_sampled: tuple[float, float, int] = (math.nan, math.nan, 0)
    budget: int | None = None  # the largest max_steps of the group's runs
    final_steps: tuple[float, float, int] = (math.nan, math.nan, 0)
    converged: int = 0  # runs that stopped on convergence before their budget


def _trend(steps: np.ndarray, values: np.ndarray) -> float:
    if len(steps) < 4:
        return math.nan
    span = steps[-1] - steps[0]
    a = steps >= steps[-1] - 0.1 * span
    b = (steps >= steps[-1] - 0.2 * span) & ~a
    if not a.any() or not b.any():
        return math.nan
    return float(np.mean(values[a]) - np.mean(values[b]))


def well_sampled(run: Run, steps: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rate summaries that rest on at least :data:`MIN_EPISODES` finished episodes (a
    summary with one episode that happened to install reads 100 %). Runs that do not log
    ``Environment/Episodes`` keep every summary."""
    if TAG_EPISODES not in run.scalars:
        return steps, values
    es, ev = run.scalars[TAG_EPISODES]
    enough = {int(x) for x, n in zip(es, ev, strict=True) if n >= MIN_EPISODES}
    keep = np.array([int(x) in enough for x in steps], bool)
    return np.asarray(steps)[keep], np.asarray(values)[keep]


def group_stats(group: int, runs: list[Run]) -> GroupStats:
    done = [r for r in runs if r.status != "error"]
    evals = [r.eval for r in done if r.eval]
    gl, steps_to, final_inst, trends = [], [], [], []
    for r in done:
        if TAG_GAIL_LOSS in r.scalars:
            gl.append(last_window_mean(*r.scalars[TAG_GAIL_LOSS], GAIL_WINDOW))
        if TAG_INSTALLED in r.scalars:
            s, v = r.scalars[TAG_INSTALLED]
            steps_to.append(steps_to_threshold(*well_sampled(r, s, v), THRESHOLD))
            final_inst.append(float(v[-1]))
            trends.append(_trend(s, v))
    tr = [t for t in trends if math.isfinite(t)]
    sampled = [r.eval_sampled for r in done if r.eval_sampled]
    budgets = [r.max_steps for r in runs if r.max_steps]
    return GroupStats(
        group=group,
        runs=runs,
        picked=mean_sd([e.get("picked_rate") for e in evals]),
        installed=mean_sd([e.get("installed_rate") for e in evals]),
        length=mean_sd([e.get("mean_episode_length") for e in evals]),
        gail_loss=mean_sd(gl),
        steps_to=steps_to,
        final_installed_train=mean_sd(final_inst),
        trend=float(np.mean(tr)) if tr else math.nan,
        picked_sampled=mean_sd([e.get("picked_rate") for e in sampled]),
        installed_sampled=mean_sd([e.get("installed_rate") for e in sampled]),
        length_sampled=mean_sd([e.get("mean_episode_length") for e in sampled]),
        budget=int(max(budgets)) if budgets else None,
        final_steps=mean_sd([r.final_step for r in done if r.eval and r.final_step]),
        converged=sum(r.converged_at is not None for r in done),
    )


def agrees(ours: tuple[float, float, int], paper: float, *, rate: bool) -> bool | None:
    m, sd, n = ours
    if n == 0:
        return None
    tol = max(RATE_TOL if rate else LENGTH_TOL * paper, 2 * sd / math.sqrt(n))  # 2 SE
    return abs(m - paper) <= tol
