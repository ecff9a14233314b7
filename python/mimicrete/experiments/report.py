"""``docs/RESULTS.md`` and ``docs/figures/`` generated from the sweep's run directories only.

``render`` is the report's sections in order (each a function returning its lines): the summary,
Table 5 beside the paper's, where we agree and differ (generated) with the human-written *why*,
Fig. 7, the GAIL loss, steps to 97 %, every run, the crashed trials, the commands to reproduce.

``python -m mimicrete.experiments.report --runs runs/experiments/runs --out docs/RESULTS.md``
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .figures import write_figures
from .markdown import listing as _list
from .markdown import num as _num
from .markdown import pct as _pct
from .markdown import steps as _steps
from .markdown import table as _table
from .paper import FIG7_PANELS, PAPER_GAIL_LOSS, PAPER_MAX_STEPS, PAPER_TABLE3, PAPER_TABLE5
from .stats import (
    GAIL_WINDOW,
    LENGTH_TOL,
    MIN_EPISODES,
    RATE_TOL,
    TAG_INSTALLED,
    THRESHOLD,
    GroupStats,
    group_stats,
    mean_sd,
)
from .sweep_runs import Run, _json, load_runs, missing_dir, sweep_parts
from .verdicts import comparison_lines

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


def _budget(runs: list[Run]) -> int | None:
    b = [r.max_steps for r in runs if r.max_steps]
    return int(max(b)) if b else None


def _budget_line(stats: dict[int, GroupStats]) -> str:
    """The step budget, or the budgets by group when the sweep ran in parts."""
    by: dict[int, list[int]] = {}
    for g, st in stats.items():
        if st.budget:
            by.setdefault(st.budget, []).append(g)
    if not by:
        return "- Step budget: unknown (no `trial.json`/`run.json`)."
    if len(by) == 1:
        b = next(iter(by))
        return (
            f"- **Step budget per run: {b:,} env steps** (the paper: {PAPER_MAX_STEPS:,}). The "
            "linear schedules (learning rate, ε, β) decay over our budget"
            + (", not over 5M." if b != PAPER_MAX_STEPS else ".")
        )
    parts = "; ".join(f"{b:,} for group(s) {_list(gs)}" for b, gs in sorted(by.items()))
    return (
        f"- **Step budget per run: {parts}** (the paper: {PAPER_MAX_STEPS:,}). The linear "
        "schedules (learning rate, ε, β) decay over each run's budget."
    )


def _convergence_line(runs: list[Run]) -> str | None:
    """How many runs had the stop on convergence, and how many stopped on it."""
    crit = None
    on = 0
    for r in runs:
        beh = r.behavior
        c = beh.get("stop_on_convergence")
        if c:
            on += 1
            crit = c
    if not on or crit is None:
        return None
    stopped = sorted(
        f"{r.name} at {_steps(r.converged_at)}" for r in runs if r.converged_at is not None
    )
    return (
        f"- Training stops once it has converged, as the paper's did (\"when the training step "
        f'reaches 5,000,000 or converges to the maximum reward"): installed ≥ '
        f"{100 * crit.get('installed_rate', 0.99):.0f} % in {crit.get('summaries', 3)} summaries "
        f"in a row, each over ≥ {crit.get('min_episodes', 20)} training episodes "
        f"(`stop_on_convergence`; {on} of {len(runs)} runs had it on). "
        + (
            f"{len(stopped)} stopped on it: {', '.join(stopped)}."
            if stopped
            else "None stopped on it."
        )
    )


def _departures(runs: list[Run]) -> list[str]:
    """Config facts (from resolved_config.yaml) that differ from ML-Agents / the paper."""
    surv, pre, idle = set(), set(), set()
    for r in runs:
        beh = r.behavior
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


# ----------------------------------------------------------------------------------------------
# the report, section by section
# ----------------------------------------------------------------------------------------------


@dataclass
class ReportInput:
    """What every section reads: the runs, per-group statistics, figures and the sweep record."""

    runs: list[Run]
    stats: dict[int, GroupStats]
    figures: dict[str, Path]
    report_path: Path
    budget: int | None
    seeds: list[int]
    sweeps: list[dict]  # every sweep record the runs came from (one per part)

    def rel(self, figure: Path) -> str:
        return os.path.relpath(figure, self.report_path.parent)


def section_summary(r: ReportInput) -> list[str]:
    runs = r.runs
    n_err = sum(x.status == "error" for x in runs)
    lines = [
        "# Results: Table 3's groups, reproduced over seeds",
        "",
        "Generated by `python -m mimicrete.experiments.report` from the run directories only (do "
        "not edit by hand, except the marked *why* section). Paper: Duan & Zou, *Learning from "
        "demonstrations: an intuitive VR environment for imitation learning of construction "
        "robots* (Tables 3 and 5, Fig. 7, §5.2).",
        "",
        f"- Runs: {len(runs)} ({len(r.stats)} groups × seeds {', '.join(map(str, r.seeds))}); "
        f"{sum(x.status == 'done' for x in runs)} finished, {n_err} crashed, "
        f"{sum(x.status not in ('done', 'error') for x in runs)} unfinished.",
        _budget_line(r.stats),
    ]
    conv = _convergence_line(runs)
    if conv:
        lines.append(conv)
    walls = [x.wall_clock_s for x in runs if x.wall_clock_s]
    if walls:
        sweep = r.sweeps[0] if len(r.sweeps) == 1 else None  # a sweep run in one part
        lines.append(
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
    lines.extend(f"- Departure: {d}." for d in _departures(runs))
    lines.append("")
    return lines


_SIGNAL_NAMES = {"extrinsic": "PPO", "gail": "GAIL"}


def run_strengths(run: Run) -> str | None:
    """The algorithms and strengths ``run`` trained with, from its ``resolved_config.yaml``, in
    Table 3's form (``PPO (1.0), GAIL (0.005), BC (0.5)``: the extrinsic reward is PPO's); None
    without a config."""
    beh = run.behavior
    if not beh:
        return None
    parts = [
        f"{_SIGNAL_NAMES.get(name, name.upper())} ({float(sig.get('strength', 1.0))})"
        for name, sig in (beh.get("reward_signals") or {}).items()
    ]
    bc = beh.get("behavioral_cloning")
    if bc:
        parts.append(f"BC ({float(bc.get('strength', 1.0))})")
    return ", ".join(parts) or "-"


def _paper_strengths(text: str) -> dict[str, float | None]:
    """Table 3's ``PPO (1.0), GAIL (0.005)`` (or a bare ``GAIL``) as {algorithm: strength}."""
    out: dict[str, float | None] = {}
    for part in text.split(","):
        name, _, rest = part.strip().partition(" (")
        out[name] = float(rest.rstrip(")")) if rest else None
    return out


def strengths_cell(runs: list[Run], paper: str) -> str:
    """The Table 5 cell: the strengths the group's runs used (distinct ones joined by `` / ``),
    with Table 3's beside them where they differ (a bare algorithm in Table 3 matches any
    strength of it)."""
    used = list(dict.fromkeys(s for s in map(run_strengths, runs) if s is not None))
    if not used:
        return "? (no resolved_config.yaml)"
    want = _paper_strengths(paper)

    def same(s: str) -> bool:
        got = _paper_strengths(s)
        return got.keys() == want.keys() and all(want[k] is None or got[k] == want[k] for k in want)

    cell = " / ".join(used)
    return cell if all(map(same, used)) else f"{cell} (Table 3: {paper})"


def section_table5(r: ReportInput) -> list[str]:
    lines = [
        "## Table 5: evaluation of the final policy, ours beside the paper's",
        "",
        "Ours, 100 episodes per run, mean ± sample standard deviation over seeds (n = seeds "
        "evaluated): **det.** is the deterministic policy (`mimicrete eval`, `eval.json`: the "
        "Gaussian's mean, each command branch's argmax); **sampl.** samples the policy "
        "(`mimicrete eval --stochastic`, `eval_stochastic.json`), as ML-Agents runs it unless "
        "`deterministic_inference` is set. The paper does not say which it used. Paper: one run "
        "per group, 100 executions. Steps: the budget, and the mean of the steps each run "
        "trained (fewer where it stopped on convergence). Algorithms (strength): what the runs "
        "trained with (their `resolved_config.yaml`; the extrinsic reward's strength is PPO's), "
        "with Table 3's beside it where it differs.",
        "",
    ]
    rows = []
    for g, st in r.stats.items():
        paper_alg, demos = PAPER_TABLE3.get(g, ("?", "?"))
        alg = strengths_cell([x for x in r.runs if x.group == g], paper_alg)
        pp, pi, pl = PAPER_TABLE5.get(g, (math.nan, math.nan, math.nan))
        steps = _steps(st.budget)
        if st.final_steps[2] and st.budget and st.final_steps[0] < 0.98 * st.budget:
            steps += f" ({_steps(st.final_steps[0])})"
        rows.append(
            [
                g,
                alg,
                demos,
                steps,
                st.installed[2],
                _pct(st.picked),
                _pct(st.picked_sampled),
                f"{100 * pp:.0f} %",
                _pct(st.installed),
                _pct(st.installed_sampled),
                f"{100 * pi:.0f} %",
                _num(st.length),
                _num(st.length_sampled),
                f"{pl:.0f}",
            ]
        )
    columns = ["Group", "Algorithms (strength)", "Demos", "Steps", "n"]
    columns += ["Picked det.", "Picked sampl.", "Picked (paper)"]
    columns += ["Installed det.", "Installed sampl.", "Installed (paper)"]
    columns += ["Length det.", "Length sampl.", "Length (paper)"]
    return [*lines, *_table(columns, rows), ""]


def section_comparison(r: ReportInput) -> list[str]:
    return [
        "## Where we agree and where we differ (generated from the numbers)",
        "",
        f"Rule: a rate agrees when |ours − paper| ≤ max({100 * RATE_TOL:.0f} points, 2 standard "
        "errors of our seed mean); an episode length when within max("
        f"{100 * LENGTH_TOL:.0f} % of the paper's, 2 standard errors).",
        "",
        *(comparison_lines(r.stats, r.budget) or ["- No evaluated runs yet."]),
        "",
        "### Why (human-written)",
        "",
        WHY_MARK,
        "",
        WHY_PLACEHOLDER,
        "",
    ]


def section_fig7(r: ReportInput) -> list[str]:
    lines = [
        "## Fig. 7: learning curves",
        "",
        "Mean over the seeds whose run reaches the step, with a 95 % Student-t confidence band "
        "of the mean (no band where one seed covers the step). A run that stopped on "
        "convergence counts at its last summary from there to the budget (its policy is final). "
        "Left: cumulative extrinsic reward per episode (Fig. 7's y axis); right: training "
        "installed rate. The curves end at our step budget: that is where each group stands at "
        "the cut.",
        "",
    ]
    for key, (title, groups) in FIG7_PANELS.items():
        if key in r.figures:
            lines += [
                f"**Fig. 7{key}, {title}** (groups {_list(groups)}):",
                "",
                f"![Fig. 7{key}]({r.rel(r.figures[key])})",
                "",
            ]
        else:
            lines += [f"**Fig. 7{key}, {title}**: no runs of groups {_list(groups)}.", ""]
    return lines


def section_gail_loss(r: ReportInput) -> list[str]:
    short = r.budget and r.budget <= GAIL_WINDOW
    lines = [
        "## GAIL loss over the last 100k steps (groups 2–4)",
        "",
        "`Losses/GAIL Loss` averaged over the summaries logged in each run's last 100,000 steps, "
        "then mean ± SD over seeds."
        + (
            f" Our runs ({_steps(r.budget)} steps) are shorter than 100k: the window is the whole"
            " run."
            if short
            else ""
        ),
        "",
    ]
    rows = []
    for g, paper in PAPER_GAIL_LOSS.items():
        st = r.stats.get(g)
        ours = _num(st.gail_loss, ".2f") if st else "–"
        n = st.gail_loss[2] if st else 0
        rows.append([g, n, ours, f"{paper:.2f}"])
    lines += _table(["Group", "n", "GAIL loss (ours)", "GAIL loss (paper)"], rows)
    if "gail" in r.figures:
        lines += ["", f"![GAIL loss]({r.rel(r.figures['gail'])})"]
    lines.append("")
    return lines


def section_steps_to_threshold(r: ReportInput) -> list[str]:
    lines = [
        f"## Steps to {100 * THRESHOLD:.0f} % installed (training)",
        "",
        f"First logged summary whose training installed rate (`{TAG_INSTALLED}`, stochastic "
        f"policy) is ≥ {100 * THRESHOLD:.0f} % over at least {MIN_EPISODES} finished episodes. "
        "The paper reports no such number; it trained "
        "until 5M steps or convergence.",
        "",
    ]
    rows = []
    for g, st in r.stats.items():
        hits = [s for s in st.steps_to if s is not None]
        per = ", ".join(_steps(s) if s is not None else "never" for s in st.steps_to) or "–"
        rows.append(
            [
                g,
                f"{len(hits)}/{len(st.steps_to)}",
                _num(mean_sd(hits), ",.0f") if hits else "–",
                per,
                _pct(st.final_installed_train),
            ]
        )
    columns = ["Group", "seeds reaching it", "steps (mean ± SD of those)", "per seed"]
    columns.append("installed rate at the cut (training)")
    return [*lines, *_table(columns, rows), ""]


def section_runs(r: ReportInput) -> list[str]:
    rows = []
    for run in r.runs:
        wc = f"{run.wall_clock_s / 60:.1f} min" if run.wall_clock_s else "–"
        sps = (
            f"{run.final_step / run.wall_clock_s:.0f}"
            if run.wall_clock_s and run.final_step and run.status == "done"
            else "–"
        )
        e, s = run.eval or {}, run.eval_sampled or {}
        rows.append(
            [
                run.name,
                run.status,
                _steps(run.final_step),
                _steps(run.converged_at) if run.converged_at is not None else "–",
                wc,
                sps,
                _pct(mean_sd([e.get("picked_rate")])),
                _pct(mean_sd([e.get("installed_rate")])),
                _num(mean_sd([e.get("mean_episode_length")])),
                _pct(mean_sd([s.get("picked_rate")])),
                _pct(mean_sd([s.get("installed_rate")])),
                _num(mean_sd([s.get("mean_episode_length")])),
            ]
        )
    columns = ["Run", "Status", "Final step", "Converged at", "Wall clock (train + eval)"]
    columns += ["Steps/s", "Picked det.", "Installed det.", "Length det."]
    columns += ["Picked sampl.", "Installed sampl.", "Length sampl."]
    return ["## Runs", "", *_table(columns, rows), ""]


def section_crashes(r: ReportInput) -> list[str]:
    lines = ["## Crashed trials", ""]
    crashed = [x for x in r.runs if x.status == "error"]
    if not crashed:
        lines.append("None.")
    for run in crashed:
        err = (run.error or "no error text recorded").strip()
        last = err.splitlines()[-1] if err else ""
        lines.append(f"- **{run.name}**: `{last[:300]}`")
        if "\n" in err:
            lines += ["", "  <details><summary>traceback</summary>", "", "  ```"]
            lines.extend("  " + ln for ln in err.splitlines()[-25:])
            lines += ["  ```", "", "  </details>"]
    lines.append("")
    return lines


def section_reproduce(r: ReportInput) -> list[str]:
    lines = [
        "## Reproduce",
        "",
        "```sh",
        "make experiments   # set-up, requirements/experiments.txt, the sweep, this report",
    ]
    cmds = [p.get("command") for s in r.sweeps for p in s.get("sweeps", [s])]
    parts = sweep_parts(r.runs)
    if all(cmds) and cmds:
        lines.extend(f"{c}   # the sweep as run" for c in cmds)
    else:  # one command per part (run root and budget) the run dirs show
        for (out, budget, conv), groups in parts.items():
            lines.append(
                f"python -m mimicrete.experiments --groups {','.join(map(str, sorted(groups)))} "
                f"--seeds {' '.join(map(str, r.seeds))}"
                + (f" --max-steps {budget}" if budget else "")
                + (" --stop-on-convergence" if conv else "")
                + (f" --out {out}" if out else "")
            )
    roots = list(dict.fromkeys(f"{out}/runs" for out, _, _ in parts if out))
    roots = roots or ["runs/experiments/runs"]
    lines += [
        "python -m mimicrete.experiments ...   # the same command again resumes it",
        "python -m mimicrete.experiments --address auto ...   # on an existing Ray cluster",
        f"python -m mimicrete.experiments.report --runs {' '.join(roots)} --out docs/RESULTS.md",
        "```",
        "",
    ]
    return lines


SECTIONS = (
    section_summary,
    section_table5,
    section_comparison,
    section_fig7,
    section_gail_loss,
    section_steps_to_threshold,
    section_runs,
    section_crashes,
    section_reproduce,
)


def render(
    runs: list[Run],
    figures: dict[str, Path],
    report_path: Path,
    sweeps: list[dict] | None = None,
) -> str:
    """The report's Markdown: every section of :data:`SECTIONS` in order."""
    by_group: dict[int, list[Run]] = {}
    for run in runs:
        by_group.setdefault(run.group, []).append(run)
    r = ReportInput(
        runs=runs,
        stats={g: group_stats(g, rs) for g, rs in sorted(by_group.items())},
        figures=figures,
        report_path=report_path,
        budget=_budget(runs),
        seeds=sorted({x.seed for x in runs}),
        sweeps=sweeps or [],
    )
    return "\n".join(line for section in SECTIONS for line in section(r))


def write_report(
    run_root: Path | list[Path],
    out: Path,
    fig_dir: Path | None = None,
    sweep_file: Path | None = None,
) -> Path:
    """The report of the runs under ``run_root`` (or several roots: a sweep run in parts, e.g.
    groups 8 and 9 at another budget), each root's ``sweep.json`` beside it unless
    ``sweep_file`` is given."""
    out = Path(out)
    fig_dir = Path(fig_dir or out.parent / "figures")
    roots = [Path(p) for p in run_root] if isinstance(run_root, list) else [Path(run_root)]
    files = [Path(sweep_file)] if sweep_file else []
    if not files:
        files = [p.parent / "sweep.json" for p in roots if (p.parent / "sweep.json").exists()]
    runs = load_runs(roots, files)
    figures = write_figures(runs, fig_dir)
    sweeps = [s for s in (_json(f) for f in files) if s]
    text = render(runs, figures, out, sweeps)
    if out.exists():
        text = keep_why(out.read_text(), text)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text)
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m mimicrete.experiments.report", description=__doc__)
    p.add_argument(
        "--runs",
        nargs="+",
        default=["runs/experiments/runs"],
        help="dir(s) of group<g>-seed<s> runs (several: a sweep run in parts; a later dir's run "
        "replaces an earlier one's of the same group and seed)",
    )
    p.add_argument("--out", default="docs/RESULTS.md")
    p.add_argument("--figures", help="figure dir (default: <out dir>/figures)")
    p.add_argument("--sweep", help="sweep.json (default: beside --runs, if there)")
    a = p.parse_args(argv)
    bad = missing_dir("--runs", a.runs)
    if bad:
        print(f"{p.prog}: error: {bad}", file=sys.stderr)
        return 2
    out = write_report(
        [Path(x) for x in a.runs],
        Path(a.out),
        Path(a.figures) if a.figures else None,
        Path(a.sweep) if a.sweep else None,
    )
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
