"""The results report (mimicrete.experiments.report, .runs, .stats) on real run dirs written here
(scalars.csv with the trainer's tags, eval.json, trial.json) whose expected numbers are computed
here by hand."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete.experiments import report, stats
from mimicrete.experiments.paper import PAPER_TABLE3
from mimicrete.experiments.sweep_runs import Run
from mimicrete.learn.run_files import read_scalars

from ._synthetic import write_run as _write_run

REPO = Path(__file__).resolve().parents[2]

# ----------------------------------------------------------------------------------------------
# the report, on synthetic run dirs
# ----------------------------------------------------------------------------------------------


def _config(group: int, gail: float | None = None) -> dict:
    """configs/group<group>.yaml as the run resolved it, GAIL's strength set to ``gail``."""
    cfg = yaml.safe_load((REPO / "configs" / f"group{group}.yaml").read_text())
    if gail is not None:
        next(iter(cfg["behaviors"].values()))["reward_signals"]["gail"]["strength"] = gail
    return cfg


def test_strengths_come_from_the_runs_configs_not_table_3():
    def run(group, cfg):
        return Run(group, 0, None, resolved=cfg)

    # what configs/group*.yaml say, in Table 3's form; matching Table 3, nothing beside it
    for g in range(1, 10):
        paper = PAPER_TABLE3[g][0]
        cell = report.strengths_cell([run(g, _config(g))], paper)
        assert "Table 3" not in cell and "?" not in cell
    assert report.strengths_cell([run(1, _config(1))], "PPO") == "PPO (1.0)"
    assert report.strengths_cell([run(2, _config(2))], "GAIL") == "GAIL (1.0)"
    assert report.run_strengths(run(6, _config(6))) == "PPO (0.5), GAIL (0.5), BC (0.5)"
    # a run trained with other strengths says so, with Table 3's beside it
    cell = report.strengths_cell([run(4, _config(4, gail=0.2))], PAPER_TABLE3[4][0])
    assert cell == "PPO (1.0), GAIL (0.2), BC (0.5) (Table 3: PPO (1.0), GAIL (0.01), BC (0.5))"
    # an algorithm Table 3 does not have for the group differs too
    cell = report.strengths_cell([run(2, _config(3))], "GAIL")
    assert cell == "PPO (1.0), GAIL (0.005), BC (0.5) (Table 3: GAIL)"
    # no resolved config: unknown, never the paper's string in its place
    assert (
        report.strengths_cell([run(3, None)], PAPER_TABLE3[3][0]) == "? (no resolved_config.yaml)"
    )


def test_report_numbers_on_synthetic_runs(tmp_path):
    root = tmp_path / "runs"
    steps = np.arange(1, 31) * 10_000  # 300k budget, a summary every 10k steps
    # group 3: three seeds reach 97 % at different steps; eval 0.9/1.0/0.95 installed
    hit = {0: 50_000, 1: 120_000, 2: 200_000}
    evals = {0: (0.95, 0.90, 100.0), 1: (1.0, 1.0, 80.0), 2: (0.97, 0.95, 90.0)}
    gail3 = {}
    for s in range(3):
        ins = np.where(steps >= hit[s], 0.98, 0.5 * steps / steps[-1])
        gl = 0.01 * (s + 1) + 1e-7 * steps  # rising: the last-100k mean is not the overall mean
        gail3[s] = gl
        # seed 2 ran with GAIL at 0.05 (a --set override), not Table 3's 0.005
        _write_run(
            root,
            3,
            s,
            steps,
            ins,
            2 * ins,
            gl,
            evals[s],
            config=_config(3, gail=0.05 if s == 2 else None),
        )
    # group 2: never installs, GAIL loss ~0.7; one seed crashed
    for s in range(2):
        _write_run(
            root,
            2,
            s,
            steps,
            np.zeros(30),
            np.full(30, 0.2),
            np.full(30, 0.7 + 0.1 * s),
            (0.2, 0.0, 750.0),
            ev_sampled=(0.1 + 0.1 * s, 0.0, 730.0 + 20 * s),
            config=_config(2),
        )
    _write_run(
        root,
        2,
        2,
        steps[:3],
        np.zeros(3),
        np.zeros(3),
        None,
        None,
        status="error",
        error="Traceback (most recent call last):\n  ...\nRuntimeError: sim exploded",
    )
    # group 1 seed 0 resumed: rows 250k..300k written twice, the later ones win
    dup = [(s, 0.0, -0.5, None) for s in (260_000, 270_000)]
    _write_run(
        root, 1, 0, steps, np.zeros(30), np.full(30, -0.1), None, (0.0, 0.0, 750.0), extra_rows=dup
    )
    # a trial that crashed before it made a run dir: only sweep.json knows it
    sweep = {
        "trials": [
            {"group": 5, "seed": 1, "status": "error", "error": "RayActorError: worker died (OOM)"}
        ],
        "sweep_wall_clock_s": 7200.0,
        "num_cpus": 2,
        "cpus_per_trial": 1,
        "command": "python -m mimicrete.experiments --max-steps 300000",
    }
    (tmp_path / "sweep.json").write_text(json.dumps(sweep))

    out = tmp_path / "docs" / "RESULTS.md"
    report.write_report(root, out)
    text = out.read_text()

    # Table 5 row of group 3: installed mean 0.95, sd 0.05 -> "95 ± 5 %"; length 90 ± 10
    # the strengths the runs used (their resolved configs), Table 3's beside them where they differ
    row3 = next(ln for ln in text.splitlines() if ln.startswith("| 3 | "))
    assert row3.startswith(
        "| 3 | PPO (1.0), GAIL (0.005), BC (0.5) / PPO (1.0), GAIL (0.05), BC (0.5) "
        "(Table 3: PPO (1.0), GAIL (0.005), BC (0.5)) |"
    )
    cells = [c.strip() for c in row3.strip("|").split("|")]
    assert cells[3] == "300k" and cells[4] == "3"
    # picked mean .9733, sd .0252; no sampled evaluation: "–"
    assert cells[5] == "97 ± 3 %" and cells[6] == "–" and cells[7] == "97 %"
    assert cells[8] == "95 ± 5 %" and cells[9] == "–" and cells[10] == "97 %"
    assert cells[11] == "90 ± 10" and cells[12] == "–" and cells[13] == "90"
    # group 2: the crashed seed is not averaged in; sampled evaluations of both seeds
    row2 = next(ln for ln in text.splitlines() if ln.startswith("| 2 | GAIL (1.0) |"))
    cells2 = [c.strip() for c in row2.strip("|").split("|")]
    assert cells2[4] == "2"
    assert cells2[6] == "15 ± 7 %" and cells2[9] == "0 ± 0 %" and cells2[12] == "740 ± 14"
    assert "Sampled policy: picked 15 %, installed 0 %, episode length 740, which agrees" in text

    # GAIL loss over the last 100k steps (summaries at steps > 200k: 210k..300k)
    keep = steps > 200_000
    ours3 = [float(np.mean(gail3[s][keep])) for s in range(3)]
    m, sd = np.mean(ours3), np.std(ours3, ddof=1)
    assert f"| 3 | 3 | {m:.2f} ± {sd:.2f} | 0.02 |" in text
    assert "| 2 | 2 | 0.75 ± 0.07 | 0.73 |" in text
    assert "| 4 | 0 | – | 1.24 |" in text

    # steps to 97 %
    srow = next(ln for ln in text.splitlines() if ln.startswith("| 3 | 3/3 |"))
    hits = [hit[s] for s in range(3)]
    assert f"{np.mean(hits):,.0f} ± {np.std(hits, ddof=1):,.0f}" in srow
    assert "50k, 120k, 200k" in srow
    assert "| 2 | 0/2 |" in text

    # comparison text generated from the numbers
    assert "- Group 3 **agrees** with the paper" in text
    assert "- Group 2 **differs** from the paper" not in text  # 20 % vs 18 %: agrees
    assert "- Group 2 **agrees**" in text
    assert report.WHY_MARK in text

    # crashes: the run dir's error and the sweep-only one
    crashed = text.split("## Crashed trials")[1].split("\n## ")[0]
    assert "group2-seed2" in crashed and "RuntimeError: sim exploded" in crashed
    assert "group5-seed1" in crashed and "worker died" in crashed
    assert "Step budget per run: 300,000 env steps" in text
    assert "python -m mimicrete.experiments --max-steps 300000" in text
    assert "the whole sweep took 2.00 h" in text

    # the resumed run's CSV: duplicate steps keep the later row
    sc = read_scalars(root / "group1-seed0" / "scalars.csv")
    s, v = sc["Environment/Cumulative Reward"]
    assert list(s) == list(steps)
    assert v[list(s).index(260_000)] == -0.5 and v[list(s).index(250_000)] == -0.1

    figs = out.parent / "figures"
    for name in ("fig7a_RL_methods.png", "fig7b_strength_coefficients.png", "gail_loss.png"):
        assert (figs / name).stat().st_size > 5000
    assert not (figs / "fig7c_demonstration_counts.png").exists()  # no runs of 4, 8, 9
    assert "![Fig. 7a](figures/fig7a_RL_methods.png)" in text


def test_report_flags_a_difference_and_the_cut(tmp_path):
    """Group 4 evaluated at 40 % installed vs the paper's 97 %, budget 200k < 5M, and its
    training curve still rising at the cut: the report says it differs, and says both."""
    root = tmp_path / "runs"
    steps = np.arange(1, 21) * 10_000
    for s in range(3):
        ins = np.linspace(0, 0.8, 20)
        _write_run(root, 4, s, steps, ins, ins, np.full(20, 1.0), (0.9, 0.4 + 0.01 * s, 500.0))
    out = tmp_path / "RESULTS.md"
    report.write_report(root, out)
    line = next(ln for ln in out.read_text().splitlines() if ln.startswith("- Group 4"))
    assert "**differs**" in line and "installed 41 % vs the paper's 97 %" in line
    assert "episode length 500 vs 173" in line
    assert "4 % of the paper's 5M" in line and "still rising at the cut" in line


# ----------------------------------------------------------------------------------------------
# statistics
# ----------------------------------------------------------------------------------------------


def test_curve_band_t_interval():
    s = np.array([0, 10, 20])
    grid, mean, lo, hi = stats.curve_band([(s, np.zeros(3)), (s, np.ones(3))], points=3)
    assert np.allclose(grid, s) and np.allclose(mean, 0.5)
    half = 12.706204736 * math.sqrt(0.5) / math.sqrt(2)  # t(0.975, 1 dof) * sd / sqrt(n)
    assert np.allclose(hi - mean, half, rtol=1e-6) and np.allclose(mean - lo, half, rtol=1e-6)
    # identical seeds: no width; one seed covering a point: no band there
    _, m2, lo2, hi2 = stats.curve_band([(s, s * 0.1), (s, s * 0.1)], points=3)
    assert np.allclose(lo2, m2) and np.allclose(hi2, m2)
    g3, m3, lo3, hi3 = stats.curve_band(
        [(s, np.ones(3)), (np.array([0, 10]), np.zeros(2))], points=3
    )
    assert m3[-1] == 1.0 and lo3[-1] == hi3[-1] == 1.0 and m3[0] == 0.5


def test_a_converged_run_is_held_at_its_last_value_to_the_budget():
    s, v = np.array([0, 10, 20]), np.array([0.0, 0.5, 1.0])
    hs, hv = stats.held_to_budget(s, v, converged_at=20, budget=50)
    assert hs.tolist() == [0, 10, 20, 50] and hv.tolist() == [0.0, 0.5, 1.0, 1.0]
    for conv, budget in ((None, 50), (20, None), (20, 20)):  # ran to the end, or no budget known
        same = stats.held_to_budget(s, v, conv, budget)
        assert same[0] is s and same[1] is v
    # the seed mean with a converged seed held: both seeds count to the end
    other = (np.array([0, 25, 50]), np.array([0.0, 0.0, 0.0]))
    _, mean, _, _ = stats.curve_band([(hs, hv), other], points=3)
    assert mean.tolist() == [0.0, 0.5, 0.5]


@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=50), st.floats(-1e3, 1e3))
@settings(max_examples=200, deadline=None)
def test_steps_to_threshold_is_first_crossing(values, thr):
    steps = np.arange(1, len(values) + 1) * 100
    got = stats.steps_to_threshold(steps, np.array(values), thr)
    first = next((i for i, v in enumerate(values) if v >= thr), None)
    assert got == (None if first is None else int(steps[first]))


def test_last_window_and_mean_sd():
    s = np.arange(1, 11) * 50_000  # last step 500k: the last 100k are 450k and 500k
    v = np.arange(10.0)
    assert stats.last_window_mean(s, v, 100_000) == pytest.approx(8.5)
    assert stats.mean_sd([1.0, 2.0, 3.0]) == (2.0, 1.0, 3)
    assert stats.mean_sd([0.5]) == (0.5, 0.0, 1)
    m, sd, n = stats.mean_sd([None, float("nan")])
    assert n == 0 and math.isnan(m)


def test_regenerating_the_report_keeps_the_why_section():
    def doc(body: str, table: str) -> str:
        head = f"# R\n\n{table}\n\n### Why (human-written)\n\n"
        return f"{head}{report.WHY_MARK}\n{body}\n## Fig. 7\n\nx\n"

    fresh = doc(f"\n{report.WHY_PLACEHOLDER}\n", "new table")
    written = doc("\nGroup 2 differs because ...\n\nAnd group 7 ...\n", "old table")
    out = report.keep_why(written, fresh)
    assert "new table" in out and "old table" not in out
    assert "Group 2 differs because ...\n\nAnd group 7 ...\n" in out
    assert report.WHY_PLACEHOLDER not in out and out.endswith("## Fig. 7\n\nx\n")
    # nothing written yet, or no mark: the new text as generated
    assert report.keep_why(fresh, fresh) == fresh
    assert report.keep_why("# an old file without the mark\n", fresh) == fresh


def test_report_lists_the_departures_from_ml_agents(tmp_path):
    def beh(g: int, **kw) -> Run:
        r = Run(g, 0, None)
        r.resolved = {"behaviors": {"TileSuction": kw}}
        return r

    runs = [
        beh(1),
        beh(
            3,
            reward_signals={"gail": {"survivor_bias": "bootstrap"}},
            behavioral_cloning={"pretrain_steps": 2000},
            demo_drop_idle=0.1,
        ),
        beh(4, reward_signals={"gail": {"survivor_bias": "none"}}, demo_drop_idle=0.0),
    ]
    deps = report._departures(runs)
    assert len(deps) == 3 and all(d.startswith("group(s) 3 ") for d in deps)
    assert "survivor_bias" in deps[0] and "pretrain_steps" in deps[1]
    assert "demo_drop_idle" in deps[2]
    assert report._departures([beh(1), beh(4)]) == []


def test_steps_to_97_needs_enough_episodes():
    r = Run(6, 0, None)
    steps = np.array([10, 20, 30, 40]) * 1000
    r.scalars = {
        "Environment/Installed Rate": (steps, np.array([0.0, 1.0, 0.5, 0.98])),
        "Environment/Episodes": (steps, np.array([30.0, 1.0, 25.0, 40.0])),
    }
    s, v = stats.well_sampled(r, *r.scalars["Environment/Installed Rate"])
    assert list(s) == [10_000, 30_000, 40_000]  # the one-episode 100 % summary is not counted
    r.status = "done"
    assert stats.group_stats(6, [r]).steps_to == [40_000]
    del r.scalars["Environment/Episodes"]  # nothing to judge by: every summary counts
    assert stats.group_stats(6, [r]).steps_to == [20_000]


def test_report_of_a_sweep_run_in_parts(tmp_path):
    """Two run roots with different budgets (groups 8 and 9 at the paper's 5M beside the rest at
    1M): the budget line names both, Table 5 gives each group's budget and the steps its runs
    trained when they stopped on convergence, and a later root's run replaces an earlier one's."""
    steps1 = np.arange(1, 11) * 100_000
    a, b = tmp_path / "a" / "runs", tmp_path / "b" / "runs"
    for s in range(2):
        _write_run(a, 3, s, steps1, np.full(10, 1.0), np.ones(10), None, (1.0, 1.0, 60.0))
        _write_run(a, 9, s, steps1, np.zeros(10), np.zeros(10), None, (0.0, 0.0, 750.0))
        stop = 2_000_000 + 500_000 * s
        steps5 = np.arange(1, stop // 100_000 + 1) * 100_000
        _write_run(
            b,
            9,
            s,
            steps5,
            np.full(len(steps5), 1.0),
            np.ones(len(steps5)),
            None,
            (1.0, 0.98, 40.0),
            max_steps=5_000_000,
            converged_at=stop,
            ev_sampled=(1.0, 0.96, 45.0),
        )
    out = tmp_path / "RESULTS.md"
    report.write_report([a, b], out)
    text = out.read_text()
    assert "1,000,000 for group(s) 3; 5,000,000 for group(s) 9" in text
    row9 = next(ln for ln in text.splitlines() if ln.startswith("| 9 |"))
    cells = [c.strip() for c in row9.strip("|").split("|")]
    assert cells[3] == "5.00M (2.25M)" and cells[4] == "2"
    assert cells[8] == "98 ± 0 %" and cells[9] == "96 ± 0 %"
    row3 = next(ln for ln in text.splitlines() if ln.startswith("| 3 |"))
    assert [c.strip() for c in row3.strip("|").split("|")][3] == "1.00M"
    runs = text.split("## Runs")[1].split("\n## ")[0]
    assert "| group9-seed1 | done | 2.50M | 2.50M |" in runs
    # no sweep record: one command per part, as the run dirs show it
    repro = text.split("## Reproduce")[1]
    assert "--groups 3 --seeds 0 1 --max-steps 1000000 --out" in repro  # 9: replaced by b
    assert "--groups 9 --seeds 0 1 --max-steps 5000000 --out" in repro


def test_report_cli_names_a_missing_runs_dir(tmp_path, capsys):
    out = tmp_path / "R.md"
    assert report.main(["--runs", str(tmp_path), str(tmp_path / "nope"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"--runs {tmp_path / 'nope'}: no such directory") and "\n" not in err
    assert not out.exists()
