"""``python -m mimicrete.experiments.peers`` end to end at a tiny budget: one demo exported, ACT
and Diffusion trained for 2 steps each by lerobot in the lerobot venv (.venv-export, which
`make test` builds), each evaluated for 2 episodes per start set in our env through the adapter,
then the table and the figure from the result files. Evaluation episodes are cut at 40 steps
(``--eval-max-steps``) to keep it short."""

from __future__ import annotations

import json
import os
import shutil
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from mimicrete.experiments import peers, peers_report

REPO = Path(__file__).resolve().parents[2]
LEROBOT_PY = Path(os.environ.get("MIMICRETE_LEROBOT_PYTHON", REPO / ".venv-export/bin/python"))


def test_dataset_gets_environment_state(one_demo, tmp_path):
    root = peers.make_dataset(one_demo, 1, tmp_path)
    info = json.loads((root / "meta/info.json").read_text())
    env = info["features"][peers.ENV_STATE]
    assert env["names"] == [f"t.{o}_{a}" for o in ("target", "tile") for a in "xyz"]
    data = pq.read_table(root / "data/chunk-000/file-000.parquet").to_pylist()
    names = info["features"]["observation.state"]["names"]
    cols = [names.index(n) for n in env["names"]]
    assert data[3][peers.ENV_STATE] == [data[3]["observation.state"][c] for c in cols]
    stats = json.loads((root / "meta/stats.json").read_text())
    # the target never moves in the demos: its std is floored, its min/max widened
    assert stats[peers.ENV_STATE]["std"][0] == peers.STAT_FLOOR
    lo, hi = stats[peers.ENV_STATE]["min"][0], stats[peers.ENV_STATE]["max"][0]
    assert hi - lo == pytest.approx(2 * peers.STAT_FLOOR)
    assert peers.make_dataset(one_demo, 1, tmp_path) == root  # made once
    with pytest.raises(peers.PeersError, match="1 demos, 2 asked for"):
        peers.make_dataset(one_demo, 2, tmp_path)


def _run(demos: Path, out: Path, methods: list[str]) -> int:
    return peers.main(
        ["run", "--demos", str(demos), "--counts", "1", "--methods", *methods,
         "--act-steps", "2", "--diffusion-steps", "2", "--batch-size", "4", "--episodes", "2",
         "--eval-max-steps", "40", "--starts", "training", "robust", "--nice", "0",
         "--lerobot-python", str(LEROBOT_PY), "--out", str(out)]
    )  # fmt: skip


def test_pipeline_end_to_end(one_demo, tmp_path):
    if not LEROBOT_PY.exists():
        pytest.fail(f"{LEROBOT_PY} missing: run `make export-venv` (lerobot 0.4.4)")
    out = tmp_path / "run"
    t0 = time.perf_counter()
    # the two methods side by side (each a training and an evaluation process, most of it
    # lerobot's imports), each in its own run dir; the results go into one for the report
    with ThreadPoolExecutor(2) as ex:
        rcs = list(ex.map(lambda m: _run(one_demo, tmp_path / m, [m]), peers.LEROBOT_METHODS))
    assert rcs == [0, 0]
    print(f"pipeline at a tiny budget: {time.perf_counter() - t0:.1f} s")
    (out / "results").mkdir(parents=True)
    for m in peers.LEROBOT_METHODS:
        for f in (tmp_path / m / "results").glob("*.json"):
            shutil.copy(f, out / "results" / f.name)
    files = sorted(p.name for p in (out / "results").glob("*.json"))
    want = [f"{m}-n1-{s}.json" for m in peers.LEROBOT_METHODS for s in ("robust", "training")]
    assert files == want
    for f in (out / "results").glob("*.json"):
        r = json.loads(f.read_text())
        for k in peers_report.RESULT_FIELDS:
            assert k in r, (f.name, k)
        assert r["episodes"] == 2 and r["steps"] == 2 and r["demos"] == 1
        # rates and the mean length are over the two whole episodes
        for k in ("installed_rate", "picked_rate", "mean_episode_length"):
            assert 2 * r[k] == pytest.approx(round(2 * r[k])), (k, r[k])
        assert 0.0 <= r["installed_rate"] <= 1.0 and 0.0 <= r["picked_rate"] <= 1.0
        assert r["max_steps"] == 40
        assert r["train_wall_s"] > 0 and r["lerobot"] == "0.4.4"
        assert r["policy_type"] == r["method"]
        assert r["action_layout"] == "level"  # trained and stepped on the suction level
        assert r["starts"] in f.name and r["eval_seed"] == 10_000 and r["seed"] == 0
    # a second run reuses everything (no training, no evaluation): no file is rewritten
    before = {f: f.stat().st_mtime_ns for f in (tmp_path / "act").rglob("*") if f.is_file()}
    assert _run(one_demo, tmp_path / "act", ["act"]) == 0
    after = {f: f.stat().st_mtime_ns for f in (tmp_path / "act").rglob("*") if f.is_file()}
    assert after == before

    doc = tmp_path / "RESULTS.md"
    doc.write_text(f"# R\n\n{peers_report.TABLE_BEGIN}\nold\n{peers_report.TABLE_END}\n\nafter\n")
    fig = tmp_path / "fig.png"
    rc = peers.main(["report", "--out", str(out), "--figure", str(fig), "--into", str(doc)])
    assert rc == 0
    assert fig.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = doc.read_text()
    assert "old" not in text and text.endswith("after\n")
    assert "| ACT (LeRobot) | 1 |" in text and "| Diffusion Policy (LeRobot) | 1 |" in text
    assert "installed (robust)" in text and "2 × 4" in text
    assert (out / "summary.md").read_text() in text


def test_bad_input_is_one_line(tmp_path, capsys):
    assert peers.main(["run", "--demos", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no such directory" in err[0]
    assert peers.main(["report", "--out", str(tmp_path)]) == 2
    assert "no such directory" in capsys.readouterr().err
    assert peers.main(["run", "--counts", "0"]) == 2
    for flag in ("--gen-count", "--paper-steps", "--our-steps"):
        capsys.readouterr()
        assert peers.main(["run", "--demos", str(tmp_path), flag, "0"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and flag in err[0] and "positive" in err[0]


def test_ours_and_paper_in_the_grid(one_demo, tmp_path, capsys):
    """Our learner (demogen + wide_gen1) and the paper's recipe (group 4) on the same first
    demo, at a tiny budget, through the same grid: result files the report tables beside the
    peers', with the env steps as the budget; a second run trains and evaluates nothing."""
    out = tmp_path / "run"
    argv = ["run", "--demos", str(one_demo), "--counts", "1", "--methods", "ours", "paper",
            "--our-steps", "512", "--paper-steps", "512", "--gen-count", "3", "--episodes", "2",
            "--starts", "training", "wide", "--nice", "0", "--out", str(out),
            "--stop-on-convergence",
            "--lerobot-python", str(tmp_path / "no-lerobot-needed")]  # fmt: skip
    assert peers.main(argv) == 0, capsys.readouterr().err
    files = sorted(p.name for p in (out / "results").glob("*.json"))
    assert files == [f"{m}-n1-{s}.json" for m in ("ours", "paper") for s in ("training", "wide")]
    for f in (out / "results").glob("*.json"):
        r = json.loads(f.read_text())
        for k in peers_report.RESULT_FIELDS:
            assert k in r, (f.name, k)
        assert r["episodes"] == 2 and r["demos"] == 1 and r["eval_seed"] == 10_000
        assert r["batch_size"] is None and r["steps"] >= 512  # the last update crosses the budget
        assert 0.0 <= r["installed_rate"] <= 1.0
        assert f"--starts {r['starts']}" in r["eval_command"]
        # the early stop reaches both trainings and is recorded (512 steps: too few to converge)
        assert r["stop_on_convergence"] is True and "--stop-on-convergence" in r["train_command"]
    ours = json.loads((out / "results" / "ours-n1-wide.json").read_text())
    assert ours["config"] == "configs/wide_gen1.yaml" and ours["gen_count"] == 3
    assert ours["gen_wall_s"] > 0 and "demogen" in ours["train_command"]
    assert len(list((out / "gen" / "n1").glob("*.mcap"))) == 3
    paper = json.loads((out / "results" / "paper-n1-training.json").read_text())
    assert paper["config"] == "configs/group4.yaml" and paper["gen_count"] is None
    assert "behavior.demo_episodes=1" in paper["train_command"]
    before = {f: f.stat().st_mtime_ns for f in out.rglob("*") if f.is_file()}
    assert peers.main(argv) == 0
    assert {f: f.stat().st_mtime_ns for f in out.rglob("*") if f.is_file()} == before
    # without the early stop the trainings are of another protocol: not reused
    plain = [a for a in argv if a != "--stop-on-convergence"]
    assert peers.main([*plain, "--methods", "paper"]) == 0
    paper2 = json.loads((out / "results" / "paper-n1-training.json").read_text())
    assert paper2["stop_on_convergence"] is False
    assert "--stop-on-convergence" not in paper2["train_command"]
    md = tmp_path / "t.md"
    assert peers.main(["report", "--out", str(out), "--md", str(md),
                       "--figure", str(tmp_path / "f.png")]) == 0  # fmt: skip
    text = md.read_text()
    assert f"| {peers_report.LABELS['ours']} | 1 |" in text
    assert f"| {peers_report.LABELS['paper']} | 1 |" in text
    assert f"{ours['steps']:,} env steps" in text and "demogen" in text


def test_the_budget_column_says_whether_a_capped_run_converged():
    """With --stop-on-convergence the step budget is a cap: a run that stopped below it converged,
    one whose last update crossed it did not; a fixed budget shows the steps alone."""
    base = {"batch_size": None, "stop_on_convergence": True, "budget_asked": 2_000_000}
    assert peers_report._budget({**base, "steps": 1_269_760}) == (
        "1,269,760 env steps (converged; cap 2,000,000)"
    )
    assert peers_report._budget({**base, "steps": 2_007_040}) == (
        "2,007,040 env steps (not converged; cap 2,000,000)"
    )
    fixed = {**base, "stop_on_convergence": False, "steps": 1_003_520}
    assert peers_report._budget(fixed) == "1,003,520 env steps"
    offline = {"batch_size": 8, "steps": 1000, "epochs": 5.05}
    assert peers_report._budget(offline) == "1000 × 8 (5.05)"
