"""The Ray Tune sweep (mimicrete.experiments) and the results report (mimicrete.report).

The sweep tests run real Ray locally on the toy env (the trainer's stand-in of the tile task) with
tiny budgets; the report tests write real run dirs (scalars.csv with the trainer's tags,
eval.json, trial.json) whose expected numbers are computed here by hand."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete import experiments, report

# A guard against a hung sweep, not a timing assertion: generous so a loaded 2-core machine passes.
HANG_S = 1200
REPO = Path(__file__).resolve().parents[1]


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------


def _toy_configs(
    cfg_dir: Path,
    *,
    max_steps: int,
    ckpt: int,
    bad_group: int | None = None,
    slow_group2: bool = False,
):
    """Group 1 (PPO only) and group 2 (PPO + GAIL + BC) on the toy env; ``bad_group`` gets a
    config the trainer rejects (an unknown key) so its trials crash."""
    from mimicrete.learn import config
    from mimicrete.learn.toyenv import toy_config

    cfg_dir.mkdir(parents=True, exist_ok=True)
    config.save(
        toy_config(cfg_dir, max_steps=max_steps, buffer=512, ckpt=ckpt, gail=0, bc=0),
        cfg_dir / "group1.yaml",
    )
    g2 = toy_config(cfg_dir, max_steps=max_steps, buffer=512, ckpt=ckpt)
    if slow_group2:
        # 512 x 3 nets and 12 epochs per update: slow enough that Ctrl-C cuts the trial even when
        # a loaded machine delays Tune's handling of it (Tune itself waits up to 5 s)
        g2.behavior.network_settings.hidden_units = 512
        g2.behavior.network_settings.num_layers = 3
        g2.behavior.hyperparameters.num_epoch = 12
    config.save(g2, cfg_dir / "group2.yaml")
    if bad_group is not None:
        (cfg_dir / f"group{bad_group}.yaml").write_text(
            "behaviors:\n  Toy:\n    trainer_type: ppo\n    not_a_key: 1\n"
        )


def _sweep_cmd(
    cfg_dir: Path,
    out: Path,
    groups: str,
    seeds: list[int],
    max_steps: int,
    num_cpus: int,
    extra: list[str] | None = None,
) -> list[str]:
    return [
        sys.executable,
        "-m",
        "mimicrete.experiments",
        "--groups",
        groups,
        "--seeds",
        *map(str, seeds),
        "--max-steps",
        str(max_steps),
        "--config-dir",
        str(cfg_dir),
        "--out",
        str(out),
        "--num-cpus",
        str(num_cpus),
        "--eval-episodes",
        "8",
        "--quiet",
        *(extra or []),
    ]


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO / "python") + os.pathsep + env.get("PYTHONPATH", "")
    env["OMP_NUM_THREADS"] = "1"
    env["RAY_DEDUP_LOGS"] = "0"
    return env


def _csv_steps(run_dir: Path) -> list[int]:
    with open(run_dir / "scalars.csv") as f:
        return [int(r["step"]) for r in csv.DictReader(f)]


# ----------------------------------------------------------------------------------------------
# the sweep through Ray, end to end
# ----------------------------------------------------------------------------------------------


def test_sweep_trial_dirs_crash_report(tmp_path):
    """2 groups x 2 seeds train and evaluate in their own run dirs; a third group with a bad
    config crashes and is listed, with its error, in sweep.json and in the report."""
    pytest.importorskip("ray", reason="requirements/experiments.txt not installed")
    cfg_dir, out = tmp_path / "configs", tmp_path / "exp"
    _toy_configs(cfg_dir, max_steps=2048, ckpt=1024, bad_group=3)
    results = tmp_path / "docs" / "RESULTS.md"
    cmd = _sweep_cmd(cfg_dir, out, "1-3", [0, 1], 2048, 2, ["--report-out", str(results)])
    p = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=HANG_S)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]

    for g in (1, 2):
        for s in (0, 1):
            rd = out / "runs" / f"group{g}-seed{s}"
            meta = json.loads((rd / "trial.json").read_text())
            assert meta["status"] == "done" and meta["group"] == g and meta["seed"] == s
            assert meta["final_step"] == 2048 and meta["wall_clock_s"] > 0
            assert _csv_steps(rd) == [512, 1024, 1536, 2048]
            ev = json.loads((rd / "eval.json").read_text())
            assert ev["episodes"] == 8 and 0 <= ev["installed_rate"] <= 1
            resolved = (rd / "resolved_config.yaml").read_text()
            assert f"seed: {s}" in resolved and "max_steps: 2048" in resolved
            assert (rd / "policy.onnx").exists()
    # the seed reached the trainer: the two seeds of group 2 did not train identically
    a = (out / "runs/group2-seed0/scalars.csv").read_text()
    b = (out / "runs/group2-seed1/scalars.csv").read_text()
    assert a != b

    sweep = json.loads((out / "sweep.json").read_text())
    assert sweep["errors"] == 2 and len(sweep["trials"]) == 6
    for t in sweep["trials"]:
        if t["group"] == 3:
            assert t["status"] == "error" and "ConfigError" in t["error"]
            assert "not_a_key" in t["error"]
        else:
            assert t["status"] == "done"
            assert t["metrics"]["final_step"] == 2048
    for s in (0, 1):
        meta = json.loads((out / f"runs/group3-seed{s}/trial.json").read_text())
        assert meta["status"] == "error" and "not_a_key" in meta["error"]

    text = results.read_text()
    assert "## Crashed trials" in text
    crashed = text.split("## Crashed trials")[1].split("## ")[0]
    assert "group3-seed0" in crashed and "group3-seed1" in crashed and "not_a_key" in crashed
    assert "Step budget per run: 2,048 env steps" in text
    assert (results.parent / "figures" / "fig7a_RL_methods.png").stat().st_size > 5000
    assert "| 1 | PPO | - | 2 |" in text  # group 1, two evaluated seeds


def test_interrupted_sweep_resumes(tmp_path):
    """One CPU: trials run one after another. Interrupt the sweep (Ctrl-C) once group 1 is done and
    group 2 (bigger nets: slow enough to be cut) has a checkpoint; the same command then restores
    the Tune experiment, does not retrain group 1, and continues group 2 from its checkpoint
    (the trainer's --resume) to the full budget."""
    pytest.importorskip("ray", reason="requirements/experiments.txt not installed")
    cfg_dir, out = tmp_path / "configs", tmp_path / "exp"
    budget = 12288
    _toy_configs(cfg_dir, max_steps=budget, ckpt=1024, slow_group2=True)
    cmd = _sweep_cmd(cfg_dir, out, "1,2", [0], budget, 1, ["--no-report"])
    proc = subprocess.Popen(
        cmd,
        env=_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    rd0, rd1 = out / "runs/group1-seed0", out / "runs/group2-seed0"
    deadline = time.monotonic() + HANG_S
    interrupted = False
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            done0 = experiments.read_trial(rd0).get("status") == "done"
            ck1 = list((rd1 / "checkpoints").glob("step_*.pt")) if rd1.exists() else []
            if done0 and ck1 and experiments.read_trial(rd1).get("status") == "running":
                # Ctrl-C twice: Tune saves its state on the first, the second skips its
                # graceful wait (which could let the running trial finish) and shuts Ray down
                proc.send_signal(signal.SIGINT)
                time.sleep(1.0)
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
                interrupted = True
                break
            time.sleep(0.05)
        log = proc.communicate(timeout=HANG_S)[0]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert interrupted, "the sweep ended before it could be interrupted:\n" + log[-3000:]
    meta1 = experiments.read_trial(rd1)
    assert meta1["status"] != "done", log[-3000:]
    assert proc.returncode == 130 and "interrupted" in log, log[-3000:]
    ck_before = max(int(p.stem.split("_")[1]) for p in (rd1 / "checkpoints").glob("step_*.pt"))
    assert 0 < ck_before < budget
    mtime0 = (rd0 / "scalars.csv").stat().st_mtime

    p = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=HANG_S)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    assert "resuming the sweep" in p.stdout
    m0, m1 = experiments.read_trial(rd0), experiments.read_trial(rd1)
    assert m0["status"] == "done" and m0["attempts"] == 1
    assert (rd0 / "scalars.csv").stat().st_mtime == mtime0  # not retrained
    assert m1["status"] == "done" and m1["attempts"] == 2 and m1["final_step"] == budget
    assert m1["segments"][-1]["resumed"] is True and m1["resumed_from_checkpoint"] is True
    assert m1["segments"][0]["seconds"] is not None  # the killed segment's time is estimated
    steps = report.read_scalars(rd1 / "scalars.csv")["Environment/Cumulative Reward"][0]
    assert steps[-1] == budget and list(steps) == sorted(set(steps))
    sweep = json.loads((out / "sweep.json").read_text())
    assert {t["status"] for t in sweep["trials"]} == {"done"}


# ----------------------------------------------------------------------------------------------
# pure parts of the sweep
# ----------------------------------------------------------------------------------------------


@given(st.sets(st.integers(1, 40), min_size=1, max_size=12))
@settings(max_examples=100, deadline=None)
def test_parse_groups_roundtrip(groups):
    assert experiments.parse_groups(",".join(map(str, sorted(groups, reverse=True)))) == sorted(
        groups
    )


def test_parse_groups_ranges_and_errors():
    assert experiments.parse_groups("1-9") == list(range(1, 10))
    assert experiments.parse_groups("3-5,8, 4") == [3, 4, 5, 8]
    for bad in ("", "5-3", "0", "x"):
        with pytest.raises(ValueError):
            experiments.parse_groups(bad)


def test_demos_needed_reads_the_groups(tmp_path):
    """The shipped configs: group 1 needs no demos; the others share one dir, 60 at most."""
    need = experiments.demos_needed(REPO / "configs", list(range(1, 10)))
    assert list(need.values()) == [60]
    assert list(need)[0] == REPO / "demos" / "suction"
    assert experiments.demos_needed(REPO / "configs", [1]) == {}
    assert experiments.demos_needed(REPO / "configs", [9]) == {REPO / "demos" / "suction": 10}


# ----------------------------------------------------------------------------------------------
# the report, on synthetic run dirs
# ----------------------------------------------------------------------------------------------


def _write_run(
    root: Path,
    group: int,
    seed: int,
    steps,
    installed,
    reward,
    gail=None,
    ev=None,
    status="done",
    wall=600.0,
    max_steps=None,
    error=None,
    extra_rows=(),
):
    from mimicrete.learn.train import TAGS

    rd = root / f"group{group}-seed{seed}"
    rd.mkdir(parents=True)
    with open(rd / "scalars.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["step", *TAGS])
        rows = list(
            zip(
                steps,
                installed,
                reward,
                gail if gail is not None else [None] * len(steps),
                strict=True,
            )
        ) + list(extra_rows)
        for s, ins, rew, gl in rows:
            row = {
                "Environment/Installed Rate": ins,
                "Environment/Cumulative Reward": rew,
                "Environment/Picked Rate": ins,
                "Losses/GAIL Loss": gl,
            }
            w.writerow([s, *["" if row.get(t) is None else repr(float(row[t])) for t in TAGS]])
    if ev is not None:
        (rd / "eval.json").write_text(
            json.dumps(
                {
                    "episodes": 100,
                    "picked_rate": ev[0],
                    "installed_rate": ev[1],
                    "mean_episode_length": ev[2],
                }
            )
        )
    (rd / "trial.json").write_text(
        json.dumps(
            {
                "group": group,
                "seed": seed,
                "status": status,
                "wall_clock_s": wall,
                "max_steps": max_steps or int(steps[-1]),
                "final_step": int(steps[-1]),
                "error": error,
            }
        )
    )
    return rd


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
        _write_run(root, 3, s, steps, ins, 2 * ins, gl, evals[s])
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
    row3 = next(ln for ln in text.splitlines() if ln.startswith("| 3 | PPO (1.0), GAIL (0.005)"))
    cells = [c.strip() for c in row3.strip("|").split("|")]
    assert cells[3] == "3"
    assert cells[4] == "97 ± 3 %" and cells[5] == "97 %"  # picked mean .9733, sd .0252
    assert cells[6] == "95 ± 5 %" and cells[7] == "97 %"
    assert cells[8] == "90 ± 10" and cells[9] == "90"
    # group 2: the crashed seed is not averaged in
    row2 = next(ln for ln in text.splitlines() if ln.startswith("| 2 | GAIL |"))
    assert [c.strip() for c in row2.strip("|").split("|")][3] == "2"

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
    sc = report.read_scalars(root / "group1-seed0" / "scalars.csv")
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
    grid, mean, lo, hi = report.curve_band([(s, np.zeros(3)), (s, np.ones(3))], points=3)
    assert np.allclose(grid, s) and np.allclose(mean, 0.5)
    half = 12.706204736 * math.sqrt(0.5) / math.sqrt(2)  # t(0.975, 1 dof) * sd / sqrt(n)
    assert np.allclose(hi - mean, half, rtol=1e-6) and np.allclose(mean - lo, half, rtol=1e-6)
    # identical seeds: no width; one seed covering a point: no band there
    _, m2, lo2, hi2 = report.curve_band([(s, s * 0.1), (s, s * 0.1)], points=3)
    assert np.allclose(lo2, m2) and np.allclose(hi2, m2)
    g3, m3, lo3, hi3 = report.curve_band(
        [(s, np.ones(3)), (np.array([0, 10]), np.zeros(2))], points=3
    )
    assert m3[-1] == 1.0 and lo3[-1] == hi3[-1] == 1.0 and m3[0] == 0.5


@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=50), st.floats(-1e3, 1e3))
@settings(max_examples=200, deadline=None)
def test_steps_to_threshold_is_first_crossing(values, thr):
    steps = np.arange(1, len(values) + 1) * 100
    got = report.steps_to_threshold(steps, np.array(values), thr)
    first = next((i for i, v in enumerate(values) if v >= thr), None)
    assert got == (None if first is None else int(steps[first]))


def test_last_window_and_mean_sd():
    s = np.arange(1, 11) * 50_000  # last step 500k: the last 100k are 450k and 500k
    v = np.arange(10.0)
    assert report.last_window_mean(s, v, 100_000) == pytest.approx(8.5)
    assert report.mean_sd([1.0, 2.0, 3.0]) == (2.0, 1.0, 3)
    assert report.mean_sd([0.5]) == (0.5, 0.0, 1)
    m, sd, n = report.mean_sd([None, float("nan")])
    assert n == 0 and math.isnan(m)


def test_run_dir_keeps_its_budget(tmp_path):
    """A run dir trained with one budget is not continued with another (the schedules decay
    over max_steps); nothing in it is touched (in a sweep, Tune lists the error)."""
    cfg_dir = tmp_path / "configs"
    _toy_configs(cfg_dir, max_steps=1024, ckpt=512)
    rd = tmp_path / "runs" / "group1-seed0"
    rd.mkdir(parents=True)
    experiments.write_trial(rd, {"group": 1, "seed": 0, "max_steps": 1024, "status": "running"})
    with pytest.raises(ValueError, match="max_steps 1024"):
        experiments.train_one(
            group=1,
            seed=0,
            config_dir=str(cfg_dir),
            run_root=str(tmp_path / "runs"),
            max_steps=2048,
        )
    assert not (rd / "scalars.csv").exists()
    assert experiments.read_trial(rd)["status"] == "running"


def _summary(name, groups, trials, wall, steps=1_000_000):
    return {
        "name": name,
        "groups": groups,
        "seeds": [0, 1],
        "max_steps": steps,
        "sweep_wall_clock_s": wall,
        "trials": [{"group": g, "seed": s, "status": st} for g, s, st in trials],
        "command": f"python -m mimicrete.experiments --name {name}",
    }


def test_sweeps_into_one_out_dir_add_up():
    first = _summary("a", [3, 4], [(3, 0, "done"), (4, 0, "error"), (4, 1, "done")], 100.0)
    second = _summary("b", [1, 4], [(1, 0, "done"), (4, 0, "done")], 50.0)
    m = experiments.merge_summaries(first, second)
    assert [(t["group"], t["seed"], t["status"]) for t in m["trials"]] == [
        (1, 0, "done"),
        (3, 0, "done"),
        (4, 0, "done"),  # trained again by the later sweep: its status wins
        (4, 1, "done"),
    ]
    assert m["groups"] == [1, 3, 4] and m["errors"] == 0 and m["max_steps"] == 1_000_000
    assert m["sweep_wall_clock_s"] == 150.0 and m["name"] == "a + b"
    assert [p["name"] for p in m["sweeps"]] == ["a", "b"]
    # a third sweep, then a resume of the second: the second's part is replaced, not added
    third = _summary("c", [2], [(2, 0, "done")], 10.0, steps=500_000)
    m3 = experiments.merge_summaries(m, third)
    assert m3["max_steps"] is None  # mixed budgets: the report reads each run's own
    again = experiments.merge_summaries(m3, _summary("b", [1], [(1, 0, "error")], 70.0))
    assert [p["name"] for p in again["sweeps"]] == ["a", "c", "b"]
    assert again["sweep_wall_clock_s"] == 180.0 and again["errors"] == 1
    # the same experiment resumed alone replaces its summary
    assert experiments.merge_summaries(first, first) == first
    # the report prints each sweep's command
    lines = report.render([], {}, Path("x.md"), m).splitlines()
    assert sum(ln.endswith("# the sweep as run") for ln in lines) == 2


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
    def beh(g: int, **kw) -> report.Run:
        r = report.Run(g, 0, None)
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
    r = report.Run(6, 0, None)
    steps = np.array([10, 20, 30, 40]) * 1000
    r.scalars = {
        "Environment/Installed Rate": (steps, np.array([0.0, 1.0, 0.5, 0.98])),
        "Environment/Episodes": (steps, np.array([30.0, 1.0, 25.0, 40.0])),
    }
    s, v = report.well_sampled(r, *r.scalars["Environment/Installed Rate"])
    assert list(s) == [10_000, 30_000, 40_000]  # the one-episode 100 % summary is not counted
    r.status = "done"
    assert report.group_stats(6, [r]).steps_to == [40_000]
    del r.scalars["Environment/Episodes"]  # nothing to judge by: every summary counts
    assert report.group_stats(6, [r]).steps_to == [20_000]
