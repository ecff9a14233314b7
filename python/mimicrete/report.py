"""``docs/RESULTS.md`` and ``docs/figures/`` generated from the sweep's run directories only.

Per run dir ``group<g>-seed<s>/`` (written by ``mimicrete.experiments`` / ``mimicrete train``):
``scalars.csv`` (ML-Agents tag names, one row per summary, ``step`` first), ``eval.json``
(``mimicrete eval``: picked_rate, installed_rate, mean_episode_length), ``trial.json`` (status,
error, wall clock, budget) and ``run.json`` (max_steps). ``sweep.json`` beside the run dirs adds
trials that crashed before writing anything.

``python -m mimicrete.report --runs runs/experiments/runs --out docs/RESULTS.md``
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import re
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

RUN_DIR_RE = re.compile(r"^group(\d+)-seed(\d+)$")

PAPER_MAX_STEPS = 5_000_000
# Duan & Zou, Table 3 (algorithms with strengths, demonstrations).
PAPER_TABLE3: dict[int, tuple[str, str]] = {
    1: ("PPO", "-"),
    2: ("GAIL", "60"),
    3: ("PPO (1.0), GAIL (0.005), BC (0.5)", "60"),
    4: ("PPO (1.0), GAIL (0.01), BC (0.5)", "60"),
    5: ("PPO (1.0), GAIL (0.1), BC (0.5)", "60"),
    6: ("PPO (0.5), GAIL (0.5), BC (0.5)", "60"),
    7: ("PPO (0.1), GAIL (1.0), BC (0.5)", "60"),
    8: ("PPO (1.0), GAIL (0.01), BC (0.5)", "20"),
    9: ("PPO (1.0), GAIL (0.01), BC (0.5)", "10"),
}
# Duan & Zou, Table 5: picked rate, installed rate, average episode length (100 executions).
PAPER_TABLE5: dict[int, tuple[float, float, float]] = {
    1: (0.00, 0.00, 750.0),
    2: (0.18, 0.00, 750.0),
    3: (0.97, 0.97, 90.0),
    4: (0.97, 0.97, 173.0),
    5: (0.93, 0.00, 712.0),
    6: (0.02, 0.00, 737.0),
    7: (0.27, 0.00, 672.0),
    8: (0.00, 0.00, 750.0),
    9: (0.97, 0.82, 128.0),
}
# §5.2: "The average GAIL loss of group 2~4 for the last 100,000 steps are 0.73, 0.02, and 1.24".
PAPER_GAIL_LOSS = {2: 0.73, 3: 0.02, 4: 1.24}
GAIL_WINDOW = 100_000
THRESHOLD = 0.97
# Fig. 7's panels as §5.1 assigns the groups: "Groups 1, 2, and 4 were applied to study the
# selection of RL methods. Groups 3~7 ... the relative strength ... Groups 4, 8, and 9 ... demos".
FIG7_PANELS: dict[str, tuple[str, list[int]]] = {
    "a": ("RL methods", [1, 2, 4]),
    "b": ("strength coefficients", [3, 4, 5, 6, 7]),
    "c": ("demonstration counts", [4, 8, 9]),
}

TAG_REWARD = "Environment/Cumulative Reward"
TAG_INSTALLED = "Environment/Installed Rate"
TAG_EPISODES = "Environment/Episodes"
MIN_EPISODES = 20  # finished episodes a rate summary needs to count for steps-to-97 %
TAG_PICKED = "Environment/Picked Rate"
TAG_GAIL_LOSS = "Losses/GAIL Loss"

# Agreement rule for the generated comparison text.
RATE_TOL = 0.10  # absolute, or 2 standard errors of the seed mean if larger
LENGTH_TOL = 0.20  # relative to the paper's length, or 2 standard errors if larger

WHY_MARK = "<!-- WHY: human-written explanation goes here -->"
WHY_PLACEHOLDER = (
    "_Not written yet: the explanation of each difference above belongs here once the full "
    "sweep has run. The generated lines above only state the data._"
)


def keep_why(old_text: str, new_text: str) -> str:
    """``new_text`` with the human-written part of ``old_text`` (from the line after
    :data:`WHY_MARK` up to the next ``## `` heading) in place of the placeholder, so that
    regenerating the report keeps the explanation."""
    if WHY_MARK not in old_text or WHY_MARK not in new_text:
        return new_text
    after = old_text.split(WHY_MARK, 1)[1]
    cut = after.find("\n## ")
    written = after if cut < 0 else after[: cut + 1]
    if WHY_PLACEHOLDER in written:
        return new_text
    head, tail = new_text.split(WHY_MARK, 1)
    cut = tail.find("\n## ")
    rest = "" if cut < 0 else tail[cut + 1 :]
    return head + WHY_MARK + written + rest


# ----------------------------------------------------------------------------------------------
# reading run dirs
# ----------------------------------------------------------------------------------------------


def read_scalars(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``scalars.csv`` -> tag -> (steps, values), sorted by step, empty cells skipped. A step
    written twice (rows logged after the last checkpoint, then again after ``--resume``) keeps
    its last row."""
    rows: dict[int, dict[str, str]] = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            try:
                step = int(float(row["step"]))
            except (KeyError, TypeError, ValueError):
                continue
            rows[step] = row
    out: dict[str, tuple[list[int], list[float]]] = {}
    for step in sorted(rows):
        for k, v in rows[step].items():
            if k == "step" or v in ("", None):
                continue
            try:
                x = float(v)
            except ValueError:
                continue
            if math.isfinite(x):
                s, vals = out.setdefault(k, ([], []))
                s.append(step)
                vals.append(x)
    return {k: (np.asarray(s, np.int64), np.asarray(v, np.float64)) for k, (s, v) in out.items()}


@dataclass
class Run:
    group: int
    seed: int
    path: Path | None
    status: str = "unknown"  # done | error | running | unknown
    error: str | None = None
    wall_clock_s: float | None = None
    max_steps: int | None = None
    final_step: int | None = None
    scalars: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    eval: dict[str, Any] | None = None
    resolved: dict[str, Any] | None = None

    @property
    def name(self) -> str:
        return f"group{self.group}-seed{self.seed}"


def _json(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None


def load_run(path: Path) -> Run | None:
    m = RUN_DIR_RE.match(path.name)
    if not m or not path.is_dir():
        return None
    run = Run(int(m.group(1)), int(m.group(2)), path)
    trial = _json(path / "trial.json") or {}
    run.status = trial.get("status", "unknown")
    run.error = trial.get("error")
    run.wall_clock_s = trial.get("wall_clock_s")
    run.final_step = trial.get("final_step")
    run.max_steps = trial.get("max_steps") or (_json(path / "run.json") or {}).get("max_steps")
    if (path / "scalars.csv").exists():
        run.scalars = read_scalars(path / "scalars.csv")
        if run.final_step is None:
            steps = [s[-1] for s, _ in run.scalars.values() if len(s)]
            run.final_step = int(max(steps)) if steps else None
    run.eval = _json(path / "eval.json")
    if run.status == "unknown" and run.eval is not None:
        run.status = "done"
    rc = path / "resolved_config.yaml"
    if rc.exists():
        import yaml

        run.resolved = yaml.safe_load(rc.read_text())
    return run


def load_runs(run_root: Path, sweep_file: Path | None = None) -> list[Run]:
    """Every ``group<g>-seed<s>`` dir under ``run_root``, plus the errored trials of
    ``sweep_file`` that left no run dir (or no error in it)."""
    runs: dict[tuple[int, int], Run] = {}
    if Path(run_root).is_dir():
        for p in sorted(Path(run_root).iterdir()):
            r = load_run(p)
            if r is not None:
                runs[(r.group, r.seed)] = r
    sweep = _json(Path(sweep_file)) if sweep_file else None
    for t in (sweep or {}).get("trials", []):
        if t.get("group") is None or t.get("seed") is None:
            continue
        key = (int(t["group"]), int(t["seed"]))
        if t.get("status") == "error":
            r = runs.get(key) or Run(key[0], key[1], None)
            if r.status != "error" or not r.error:
                r.status = "error"
                r.error = r.error or t.get("error")
            runs[key] = r
    return [runs[k] for k in sorted(runs)]


# ----------------------------------------------------------------------------------------------
# statistics
# ----------------------------------------------------------------------------------------------


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


# ----------------------------------------------------------------------------------------------
# per-group aggregation
# ----------------------------------------------------------------------------------------------


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
    )


def agrees(ours: tuple[float, float, int], paper: float, *, rate: bool) -> bool | None:
    m, sd, n = ours
    if n == 0:
        return None
    tol = max(RATE_TOL if rate else LENGTH_TOL * paper, 2 * sd / math.sqrt(n))  # 2 SE
    return abs(m - paper) <= tol


# ----------------------------------------------------------------------------------------------
# formatting
# ----------------------------------------------------------------------------------------------


def _pct(ms: tuple[float, float, int]) -> str:
    m, sd, n = ms
    if n == 0:
        return "–"
    return f"{100 * m:.0f} ± {100 * sd:.0f} %" if n > 1 else f"{100 * m:.0f} %"


def _num(ms: tuple[float, float, int], fmt: str = ".0f") -> str:
    m, sd, n = ms
    if n == 0:
        return "–"
    return f"{m:{fmt}} ± {sd:{fmt}}" if n > 1 else f"{m:{fmt}}"


def _steps(x: float | int | None) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    x = float(x)
    if x >= 1e6:
        return f"{x / 1e6:.2f}M"
    if x >= 1e3:
        return f"{x / 1e3:.0f}k"
    return f"{x:.0f}"


def _budget(runs: list[Run]) -> int | None:
    b = [r.max_steps for r in runs if r.max_steps]
    return int(max(b)) if b else None


def _departures(runs: list[Run]) -> list[str]:
    """Config facts (from resolved_config.yaml) that differ from ML-Agents / the paper."""
    surv, pre, idle = set(), set(), set()
    for r in runs:
        beh = next(iter(((r.resolved or {}).get("behaviors") or {}).values()), None) or {}
        g = (beh.get("reward_signals") or {}).get("gail") or {}
        if g.get("survivor_bias") not in (None, "none"):
            surv.add(r.group)
        bc = beh.get("behavioral_cloning") or {}
        if (bc.get("pretrain_steps") or 0) > 0:
            pre.add(r.group)
        if (beh.get("demo_drop_idle") or 0) > 0:
            idle.add(r.group)
    out = []
    if surv:
        out.append(
            f"group(s) {_list(surv)} ran with `gail.survivor_bias: bootstrap` (a termination is a "
            "non-event for the GAIL signal; ML-Agents, which the paper used, is `none`), see "
            "`python/mimicrete/learn/README.md`"
        )
    if pre:
        out.append(
            f"group(s) {_list(pre)} ran with an offline BC warm start "
            "(`behavioral_cloning.pretrain_steps` > 0; ML-Agents has none)"
        )
    if idle:
        out.append(
            f"group(s) {_list(idle)} left the demonstrator's idle steps out of BC and GAIL "
            "(`demo_drop_idle` > 0; ML-Agents uses every step)"
        )
    return out


def _list(gs) -> str:
    return ", ".join(str(g) for g in sorted(gs))


def comparison_lines(stats: dict[int, GroupStats], budget: int | None) -> list[str]:
    """Generated sentences: where each group agrees with Table 5 and where it does not."""
    lines = []
    for g, st in sorted(stats.items()):
        if g not in PAPER_TABLE5 or st.installed[2] == 0:
            continue
        pp, pi, pl = PAPER_TABLE5[g]
        parts, diffs = [], []
        for label, ours, paper, rate in (
            ("picked", st.picked, pp, True),
            ("installed", st.installed, pi, True),
            ("episode length", st.length, pl, False),
        ):
            ok = agrees(ours, paper, rate=rate)
            if ok is None:
                continue
            if rate:
                txt = f"{label} {100 * ours[0]:.0f} % vs the paper's {100 * paper:.0f} %"
            else:
                txt = f"{label} {ours[0]:.0f} vs {paper:.0f}"
            (parts if ok else diffs).append(txt)
        if not diffs:
            lines.append(f"- Group {g} **agrees** with the paper ({'; '.join(parts)}).")
            continue
        s = f"- Group {g} **differs** from the paper: {'; '.join(diffs)}"
        if parts:
            s += f" (agrees on {'; '.join(parts)})"
        s += "."
        hints = []
        if budget and budget < PAPER_MAX_STEPS and st.installed[0] < pi:
            hints.append(
                f"our budget was {_steps(budget)} steps, {100 * budget / PAPER_MAX_STEPS:.0f} % "
                "of the paper's 5M"
            )
            if math.isfinite(st.trend) and st.trend > 0.05:
                hints.append(
                    "its training installed rate was still rising at the cut "
                    f"(+{100 * st.trend:.0f} points over the last 10 % of steps)"
                )
        if hints:
            s += " Data: " + "; ".join(hints) + "."
        lines.append(s)
    return lines


# ----------------------------------------------------------------------------------------------
# figures
# ----------------------------------------------------------------------------------------------


def _plot_panel(ax, runs_by_group: dict[int, list[Run]], groups: list[int], tag: str) -> bool:
    drew = False
    for g in groups:
        curves = [r.scalars[tag] for r in runs_by_group.get(g, []) if tag in r.scalars]
        if not curves:
            continue
        grid, mean, lo, hi = curve_band(curves)
        if tag in (TAG_INSTALLED, TAG_PICKED):  # a rate's band stays inside [0, 1]
            lo, hi = np.clip(lo, 0.0, 1.0), np.clip(hi, 0.0, 1.0)
        (line,) = ax.plot(grid, mean, lw=1.5, label=f"Group {g} (n={len(curves)})")
        ax.fill_between(grid, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
        drew = True
    return drew


def write_figures(runs: list[Run], fig_dir: Path) -> dict[str, Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    by_group: dict[int, list[Run]] = {}
    for r in runs:
        if r.status != "error" and r.scalars:
            by_group.setdefault(r.group, []).append(r)
    out: dict[str, Path] = {}
    for key, (title, groups) in FIG7_PANELS.items():
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        drew = False
        for ax, (tag, ylabel) in zip(
            axes,
            ((TAG_REWARD, "cumulative reward"), (TAG_INSTALLED, "installed rate (training)")),
            strict=True,
        ):
            drew |= _plot_panel(ax, by_group, groups, tag)
            ax.set_xlabel("env steps")
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=8)
        fig.suptitle(f"Fig. 7{key}: {title} (mean over seeds, 95 % CI)")
        fig.tight_layout()
        if drew:
            p = fig_dir / f"fig7{key}_{title.replace(' ', '_')}.png"
            fig.savefig(p, dpi=100)
            out[key] = p
        plt.close(fig)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    if _plot_panel(ax, by_group, sorted(PAPER_GAIL_LOSS), TAG_GAIL_LOSS):
        ax.set_xlabel("env steps")
        ax.set_ylabel("GAIL loss")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title("GAIL loss, groups 2–4 (mean over seeds, 95 % CI)")
        fig.tight_layout()
        p = fig_dir / "gail_loss.png"
        fig.savefig(p, dpi=100)
        out["gail"] = p
    plt.close(fig)
    return out


# ----------------------------------------------------------------------------------------------
# the report
# ----------------------------------------------------------------------------------------------


def render(
    runs: list[Run], figures: dict[str, Path], report_path: Path, sweep: dict | None = None
) -> str:
    by_group: dict[int, list[Run]] = {}
    for r in runs:
        by_group.setdefault(r.group, []).append(r)
    stats = {g: group_stats(g, rs) for g, rs in sorted(by_group.items())}
    budget = _budget(runs)
    seeds = sorted({r.seed for r in runs})
    L: list[str] = []
    L.append("# Results: Table 3's groups, reproduced over seeds")
    L.append("")
    L.append(
        "Generated by `python -m mimicrete.report` from the run directories only (do not edit by "
        "hand, except the marked *why* section). Paper: Duan & Zou, *Learning from "
        "demonstrations: an intuitive VR environment for imitation learning of construction "
        "robots* (Tables 3 and 5, Fig. 7, §5.2)."
    )
    L.append("")
    n_err = sum(r.status == "error" for r in runs)
    L.append(
        f"- Runs: {len(runs)} ({len(by_group)} groups × seeds {', '.join(map(str, seeds))}); "
        f"{sum(r.status == 'done' for r in runs)} finished, {n_err} crashed, "
        f"{sum(r.status not in ('done', 'error') for r in runs)} unfinished."
    )
    L.append(
        f"- **Step budget per run: {budget:,} env steps** (the paper: {PAPER_MAX_STEPS:,}). The "
        "linear schedules (learning rate, ε, β) decay over our budget, not over 5M."
        if budget
        else "- Step budget: unknown (no `trial.json`/`run.json`)."
    )
    walls = [r.wall_clock_s for r in runs if r.wall_clock_s]
    if walls:
        L.append(
            f"- Wall clock per run: mean {np.mean(walls) / 60:.1f} min, min "
            f"{min(walls) / 60:.1f}, max {max(walls) / 60:.1f} (total {sum(walls) / 3600:.2f} "
            "trial-hours)"
            + (
                f"; the whole sweep took {sweep['sweep_wall_clock_s'] / 3600:.2f} h on "
                f"{sweep.get('num_cpus')} CPU(s), {sweep.get('cpus_per_trial')} per trial."
                if sweep and sweep.get("sweep_wall_clock_s")
                else "."
            )
        )
    for d in _departures(runs):
        L.append(f"- Departure: {d}.")
    L.append("")

    # Table 5
    L.append("## Table 5: evaluation of the final policy, ours beside the paper's")
    L.append("")
    L.append(
        "Ours: `mimicrete eval` (deterministic policy, `eval.json`), mean ± sample standard "
        "deviation over seeds (n = seeds evaluated). Paper: one run per group, 100 executions."
    )
    L.append("")
    L.append(
        "| Group | Algorithms (strength) | Demos | n | Picked (ours) | Picked (paper) | "
        "Installed (ours) | Installed (paper) | Episode length (ours) | Episode length (paper) |"
    )
    L.append("|---|---|---|---|---|---|---|---|---|---|")
    for g, st in stats.items():
        alg, demos = PAPER_TABLE3.get(g, ("?", "?"))
        pp, pi, pl = PAPER_TABLE5.get(g, (math.nan, math.nan, math.nan))
        L.append(
            f"| {g} | {alg} | {demos} | {st.installed[2]} | {_pct(st.picked)} | {100 * pp:.0f} % | "
            f"{_pct(st.installed)} | {100 * pi:.0f} % | {_num(st.length)} | {pl:.0f} |"
        )
    L.append("")

    # comparison
    L.append("## Where we agree and where we differ (generated from the numbers)")
    L.append("")
    L.append(
        f"Rule: a rate agrees when |ours − paper| ≤ max({100 * RATE_TOL:.0f} points, 2 standard "
        "errors of our seed mean); an episode length when within max("
        f"{100 * LENGTH_TOL:.0f} % of the paper's, 2 standard errors)."
    )
    L.append("")
    L.extend(comparison_lines(stats, budget) or ["- No evaluated runs yet."])
    L.append("")
    L.append("### Why (human-written)")
    L.append("")
    L.append(WHY_MARK)
    L.append("")
    L.append(WHY_PLACEHOLDER)
    L.append("")

    # Fig 7
    L.append("## Fig. 7: learning curves")
    L.append("")
    L.append(
        "Mean over seeds with a 95 % Student-t confidence band of the mean (no band where one "
        "seed covers the step). Left: cumulative extrinsic reward per episode (Fig. 7's y axis); "
        "right: training installed rate. The curves end at our step budget: that is where each "
        "group stands at the cut."
    )
    L.append("")
    for key, (title, groups) in FIG7_PANELS.items():
        if key in figures:
            rel = os.path.relpath(figures[key], report_path.parent)
            L.append(f"**Fig. 7{key}, {title}** (groups {_list(groups)}):")
            L.append("")
            L.append(f"![Fig. 7{key}]({rel})")
            L.append("")
        else:
            L.append(f"**Fig. 7{key}, {title}**: no runs of groups {_list(groups)}.")
            L.append("")

    # GAIL loss
    L.append("## GAIL loss over the last 100k steps (groups 2–4)")
    L.append("")
    L.append(
        "`Losses/GAIL Loss` averaged over the summaries logged in each run's last 100,000 steps, "
        "then mean ± SD over seeds."
        + (
            f" Our runs ({_steps(budget)} steps) are shorter than 100k: the window is the whole"
            " run."
            if budget and budget <= GAIL_WINDOW
            else ""
        )
    )
    L.append("")
    L.append("| Group | n | GAIL loss (ours) | GAIL loss (paper) |")
    L.append("|---|---|---|---|")
    for g, paper in PAPER_GAIL_LOSS.items():
        st = stats.get(g)
        ours = _num(st.gail_loss, ".2f") if st else "–"
        n = st.gail_loss[2] if st else 0
        L.append(f"| {g} | {n} | {ours} | {paper:.2f} |")
    if "gail" in figures:
        L.append("")
        L.append(f"![GAIL loss]({os.path.relpath(figures['gail'], report_path.parent)})")
    L.append("")

    # steps to 97%
    L.append(f"## Steps to {100 * THRESHOLD:.0f} % installed (training)")
    L.append("")
    L.append(
        f"First logged summary whose training installed rate (`{TAG_INSTALLED}`, stochastic "
        f"policy) is ≥ {100 * THRESHOLD:.0f} % over at least {MIN_EPISODES} finished episodes. "
        "The paper reports no such number; it trained "
        "until 5M steps or convergence."
    )
    L.append("")
    L.append(
        "| Group | seeds reaching it | steps (mean ± SD of those) | per seed | "
        "installed rate at the cut (training) |"
    )
    L.append("|---|---|---|---|---|")
    for g, st in stats.items():
        hits = [s for s in st.steps_to if s is not None]
        per = ", ".join(_steps(s) if s is not None else "never" for s in st.steps_to) or "–"
        L.append(
            f"| {g} | {len(hits)}/{len(st.steps_to)} | "
            f"{_num(mean_sd(hits), ',.0f') if hits else '–'} | {per} | "
            f"{_pct(st.final_installed_train)} |"
        )
    L.append("")

    # per-run table
    L.append("## Runs")
    L.append("")
    L.append(
        "| Run | Status | Final step | Wall clock (train + eval) | Steps/s | Picked | Installed "
        "| Length |"
    )
    L.append("|---|---|---|---|---|---|---|---|")
    for r in runs:
        wc = f"{r.wall_clock_s / 60:.1f} min" if r.wall_clock_s else "–"
        sps = (
            f"{r.final_step / r.wall_clock_s:.0f}"
            if r.wall_clock_s and r.final_step and r.status == "done"
            else "–"
        )
        e = r.eval or {}
        L.append(
            f"| {r.name} | {r.status} | {_steps(r.final_step)} | {wc} | {sps} | "
            f"{_pct(mean_sd([e.get('picked_rate')]))} | "
            f"{_pct(mean_sd([e.get('installed_rate')]))} | "
            f"{_num(mean_sd([e.get('mean_episode_length')]))} |"
        )
    L.append("")

    # crashes
    L.append("## Crashed trials")
    L.append("")
    crashed = [r for r in runs if r.status == "error"]
    if not crashed:
        L.append("None.")
    for r in crashed:
        err = (r.error or "no error text recorded").strip()
        last = err.splitlines()[-1] if err else ""
        L.append(f"- **{r.name}**: `{last[:300]}`")
        if "\n" in err:
            L.append("")
            L.append("  <details><summary>traceback</summary>")
            L.append("")
            L.append("  ```")
            L.extend("  " + ln for ln in err.splitlines()[-25:])
            L.append("  ```")
            L.append("")
            L.append("  </details>")
    L.append("")

    # commands
    L.append("## Reproduce")
    L.append("")
    L.append("```sh")
    L.append("make experiments   # set-up, requirements/experiments.txt, the sweep, this report")
    cmds = [p.get("command") for p in (sweep or {}).get("sweeps", [sweep or {}])]
    if all(cmds) and cmds:
        for c in cmds:
            L.append(f"{c}   # the sweep as run")
    else:
        L.append(
            f"python -m mimicrete.experiments --groups 1-9 --seeds {' '.join(map(str, seeds))}"
            + (f" --max-steps {budget}" if budget else "")
        )
    L.append("python -m mimicrete.experiments ...   # the same command again resumes it")
    L.append("python -m mimicrete.experiments --address auto ...   # on an existing Ray cluster")
    L.append("python -m mimicrete.report --runs runs/experiments/runs --out docs/RESULTS.md")
    L.append("```")
    L.append("")
    return "\n".join(L)


def write_report(
    run_root: Path,
    out: Path,
    fig_dir: Path | None = None,
    sweep_file: Path | None = None,
) -> Path:
    out = Path(out)
    fig_dir = Path(fig_dir or out.parent / "figures")
    if sweep_file is None and (Path(run_root).parent / "sweep.json").exists():
        sweep_file = Path(run_root).parent / "sweep.json"
    runs = load_runs(Path(run_root), sweep_file)
    figures = write_figures(runs, fig_dir)
    sweep = _json(Path(sweep_file)) if sweep_file else None
    text = render(runs, figures, out, sweep)
    if out.exists():
        text = keep_why(out.read_text(), text)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m mimicrete.report", description=__doc__)
    p.add_argument("--runs", default="runs/experiments/runs", help="dir of group<g>-seed<s> runs")
    p.add_argument("--out", default="docs/RESULTS.md")
    p.add_argument("--figures", help="figure dir (default: <out dir>/figures)")
    p.add_argument("--sweep", help="sweep.json (default: beside --runs, if there)")
    a = p.parse_args(argv)
    out = write_report(
        Path(a.runs),
        Path(a.out),
        Path(a.figures) if a.figures else None,
        Path(a.sweep) if a.sweep else None,
    )
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
