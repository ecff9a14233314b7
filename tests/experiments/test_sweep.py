"""The Ray Tune sweep (mimicrete.experiments.sweep, .trials).

The sweep tests run real Ray locally on the toy env (the trainer's stand-in of the tile task) with
tiny budgets."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete.experiments import report, sweep, trials
from mimicrete.learn.run_files import read_scalars

# A guard against a hung sweep, not a timing assertion: generous so a loaded 2-core machine passes.
HANG_S = 1200
REPO = Path(__file__).resolve().parents[2]


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
    from mimicrete.testing.toyenv import toy_config

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
            sampled = json.loads((rd / "eval_stochastic.json").read_text())
            assert sampled["episodes"] == 8 and sampled["policy"] == "stochastic"
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
    assert "| 1 | PPO (1.0) | - | 2k | 2 |" in text  # group 1: 2,048 steps, two evaluated seeds


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
            done0 = trials.read_trial(rd0).get("status") == "done"
            ck1 = list((rd1 / "checkpoints").glob("step_*.pt")) if rd1.exists() else []
            if done0 and ck1 and trials.read_trial(rd1).get("status") == "running":
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
    meta1 = trials.read_trial(rd1)
    assert meta1["status"] != "done", log[-3000:]
    assert proc.returncode == 130 and "interrupted" in log, log[-3000:]
    ck_before = max(int(p.stem.split("_")[1]) for p in (rd1 / "checkpoints").glob("step_*.pt"))
    assert 0 < ck_before < budget
    mtime0 = (rd0 / "scalars.csv").stat().st_mtime

    p = subprocess.run(cmd, env=_env(), capture_output=True, text=True, timeout=HANG_S)
    assert p.returncode == 0, p.stdout[-3000:] + p.stderr[-3000:]
    assert "resuming the sweep" in p.stdout
    m0, m1 = trials.read_trial(rd0), trials.read_trial(rd1)
    assert m0["status"] == "done" and m0["attempts"] == 1
    assert (rd0 / "scalars.csv").stat().st_mtime == mtime0  # not retrained
    assert m1["status"] == "done" and m1["attempts"] == 2 and m1["final_step"] == budget
    assert m1["segments"][-1]["resumed"] is True and m1["resumed_from_checkpoint"] is True
    assert m1["segments"][0]["seconds"] is not None  # the killed segment's time is estimated
    steps = read_scalars(rd1 / "scalars.csv")["Environment/Cumulative Reward"][0]
    assert steps[-1] == budget and list(steps) == sorted(set(steps))
    sweep = json.loads((out / "sweep.json").read_text())
    assert {t["status"] for t in sweep["trials"]} == {"done"}


# ----------------------------------------------------------------------------------------------
# pure parts of the sweep
# ----------------------------------------------------------------------------------------------


@given(st.sets(st.integers(1, 40), min_size=1, max_size=12))
@settings(max_examples=100, deadline=None)
def test_parse_groups_roundtrip(groups):
    assert sweep.parse_groups(",".join(map(str, sorted(groups, reverse=True)))) == sorted(groups)


def test_parse_groups_ranges_and_errors():
    assert sweep.parse_groups("1-9") == list(range(1, 10))
    assert sweep.parse_groups("3-5,8, 4") == [3, 4, 5, 8]
    for bad in ("", "5-3", "0", "x"):
        with pytest.raises(ValueError):
            sweep.parse_groups(bad)


def test_demos_needed_reads_the_groups(tmp_path):
    """The shipped configs: group 1 needs no demos; the others share one dir, 60 at most."""
    need = sweep.demos_needed(REPO / "configs", list(range(1, 10)))
    assert list(need.values()) == [60]
    assert list(need)[0] == REPO / "demos" / "suction"
    assert sweep.demos_needed(REPO / "configs", [1]) == {}
    assert sweep.demos_needed(REPO / "configs", [9]) == {REPO / "demos" / "suction": 10}


def test_run_dir_keeps_its_budget(tmp_path):
    """A run dir trained with one budget is not continued with another (the schedules decay
    over max_steps); nothing in it is touched (in a sweep, Tune lists the error)."""
    cfg_dir = tmp_path / "configs"
    _toy_configs(cfg_dir, max_steps=1024, ckpt=512)
    rd = tmp_path / "runs" / "group1-seed0"
    rd.mkdir(parents=True)
    trials.write_trial(rd, {"group": 1, "seed": 0, "max_steps": 1024, "status": "running"})
    with pytest.raises(ValueError, match="max_steps 1024"):
        trials.train_one(
            group=1,
            seed=0,
            config_dir=str(cfg_dir),
            run_root=str(tmp_path / "runs"),
            max_steps=2048,
        )
    assert not (rd / "scalars.csv").exists()
    assert trials.read_trial(rd)["status"] == "running"


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
    m = sweep.merge_summaries(first, second)
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
    m3 = sweep.merge_summaries(m, third)
    assert m3["max_steps"] is None  # mixed budgets: the report reads each run's own
    again = sweep.merge_summaries(m3, _summary("b", [1], [(1, 0, "error")], 70.0))
    assert [p["name"] for p in again["sweeps"]] == ["a", "c", "b"]
    assert again["sweep_wall_clock_s"] == 180.0 and again["errors"] == 1
    # the same experiment resumed alone replaces its summary
    assert sweep.merge_summaries(first, first) == first
    # the report prints each sweep's command
    lines = report.render([], {}, Path("x.md"), [m]).splitlines()
    assert sum(ln.endswith("# the sweep as run") for ln in lines) == 2


def test_stop_on_convergence_flag_reaches_every_trial(tmp_path):
    pytest.importorskip("ray", reason="requirements/experiments.txt not installed")
    from mimicrete.experiments.__main__ import build_parser
    from mimicrete.experiments.sweep import (
        CONVERGENCE_OVERRIDE,
        NO_OVERLAP_OVERRIDE,
        build_param_space,
    )
    from mimicrete.learn import config
    from mimicrete.testing.toyenv import toy_config

    args = build_parser().parse_args(["--stop-on-convergence", "--set", "behavior.beta=0.01"])
    space = build_param_space(args, [1], [0])
    assert space["overrides"] == ["behavior.beta=0.01", CONVERGENCE_OVERRIDE, NO_OVERLAP_OVERRIDE]
    cfg = config.with_overrides(toy_config(tmp_path), [CONVERGENCE_OVERRIDE])
    assert cfg.behavior.stop_on_convergence == config.ConvergenceSettings()
    # a trial with 2 CPUs overlaps GAIL's steps with PPO (the config's default)
    plain = build_parser().parse_args(["--cpus-per-trial", "2"])
    assert build_param_space(plain, [1], [0])["overrides"] == []
