"""`python train.py` on a fresh checkout (configs and train.py, no demos): it makes the demos the
way `make demos-place` does, generates the wide-start demos from 5 of them, says so, and trains
the main job, TilePlace (issue 12: it stopped with "demo path demos/suction does not exist"); it
evaluates on the training and the wide starts, prints where the tiles ended, compares with another
policy on the very same starts, and draws the success maps (issue 22 §4, issue 46)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SMALL = [
    "--max-steps", "1024", "--num-envs", "8", "--no-progress", "--eval-episodes", "2",
    "--set", "behavior.hyperparameters.buffer_size=512",
    "--set", "behavior.hyperparameters.batch_size=256",
    "--set", "behavior.network_settings.hidden_units=32",
    "--set", "behavior.behavioral_cloning.pretrain_steps=5",
    "--set", "behavior.behavioral_cloning.generate_count=6",
    "--set", "behavior.behavioral_cloning.samples_per_update=512",
]  # fmt: skip


@pytest.mark.slow
def test_train_py_on_a_fresh_checkout_makes_the_demos_and_trains(tmp_path):
    shutil.copytree(REPO / "configs", tmp_path / "configs")
    shutil.copy(REPO / "train.py", tmp_path / "train.py")
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO / "python") + os.pathsep + env.get("PYTHONPATH", "")
    r = subprocess.run(
        [sys.executable, "train.py", *SMALL],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=1800,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert "demos: demos/place has 0 episodes, making 60" in r.stdout
    made = "demos: demos/gen_place5_x4 has 0 episodes, generating 6 at the wide starts from the "
    assert made + "first 5 of demos/place" in r.stdout and "--speed 4`" in r.stdout
    assert len(list((tmp_path / "demos/place").glob("*.mcap"))) == 60
    assert len(list((tmp_path / "demos/gen_place5_x4").glob("*.mcap"))) == 6
    run = tmp_path / "runs/place_gen5-seed0"
    assert json.loads((run / "run.json").read_text())["demos"] == "demos/gen_place5_x4"
    assert json.loads((run / "eval.json").read_text())["episodes"] == 2
    wide = json.loads((run / "eval_wide.json").read_text())
    assert wide["starts"] == "wide" and len(wide["per_episode"]) == 2
    for ep in wide["per_episode"]:  # each episode's start, inside TilePlace's wide box
        x, y, yaw = ep["object_pose"]
        assert 0.055 <= x <= 0.285 and 0.26 <= y <= 0.36 and abs(yaw) <= 0.5236
        assert ep["installed"] in (True, False) and 1 <= ep["length"] <= 750
    assert "place_gen5-seed0, wide starts" in r.stdout and "trained 1024 steps" in r.stdout
    for where in ("training", "wide"):  # the placement tables under the rows
        assert f"place_gen5-seed0, {where} starts:\nplacement (2 episodes)" in r.stdout
    assert "placed by the placed rule" in r.stdout
    assert (run / "success_map.png").stat().st_size > 10_000
    # the hand logs are the ones `make demos-place` writes (synth-hands --episodes 60 --seed 0)
    from mimicrete import cli

    assert cli.main(["synth-hands", "--task", "place", "--episodes", "60", "--seed", "0",
                     "--out", str(tmp_path / "make_demos")]) == 0  # fmt: skip
    made = sorted((tmp_path / "data/hands/place").iterdir())
    assert [p.name for p in made] == sorted(p.name for p in (tmp_path / "make_demos").iterdir())
    assert all(p.read_bytes() == (tmp_path / "make_demos" / p.name).read_bytes() for p in made)
    # a second `python train.py` finds the demos (and the run) and does not make them again
    # (and the generated ones): with the first run's policy beside, on the very same starts
    first = tmp_path / "first.pt"
    shutil.copy(run / "policy.pt", first)
    r2 = subprocess.run(
        [sys.executable, "train.py", *SMALL, "--force", "--compare", str(first)],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=1800,
    )  # fmt: skip
    assert r2.returncode == 0, r2.stderr[-3000:]
    assert "making" not in r2.stdout and "generating" not in r2.stdout
    assert "first, training starts" in r2.stdout and "first, wide starts" in r2.stdout
    wide2 = json.loads((run / "eval_wide.json").read_text())

    def starts(res):  # episodes are listed in finishing order
        return sorted(e["object_pose"] for e in res["per_episode"])

    assert starts(wide2) == starts(wide)  # the same seed, the same starts
    theirs = json.loads((run / "compare/first/eval_wide.json").read_text())
    assert starts(theirs) == starts(wide2)  # the compared policy's, kept with the run


def test_train_refuses_a_compare_policy_that_is_not_there(tmp_path):
    sys.path.insert(0, str(REPO / "tests"))
    from _cli_run import run_cli

    r = run_cli("train", "--config", str(REPO / "configs/wide_gen.yaml"), "--compare",
                str(tmp_path / "nope.pt"), "--run-dir", str(tmp_path / "run"))  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"--compare {tmp_path / 'nope.pt'}: no such policy file" in r.stderr
    assert not (tmp_path / "run").exists()


def test_train_refuses_a_compare_file_that_is_not_a_policy(tmp_path):
    """Checked before training: a file that torch cannot read as a policy is named, exit 2."""
    sys.path.insert(0, str(REPO / "tests"))
    from _cli_run import run_cli

    junk = tmp_path / "notes.pt"
    junk.write_text("not a policy\n")
    r = run_cli("train", "--config", str(REPO / "configs/wide_gen.yaml"), "--compare",
                str(junk), "--run-dir", str(tmp_path / "run"))  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"--compare {junk}: not a readable policy" in r.stderr
    assert not (tmp_path / "run").exists()


def test_train_refuses_a_compare_policy_of_another_task(tmp_path):
    """The paper's TileSuction policy beside a BlockGrip run would print rows of two tasks as one
    table: refused before training, naming both."""
    sys.path.insert(0, str(REPO / "tests"))
    from _cli_run import run_cli

    paper = REPO / "tests/learn/data/group3_policy.pt"
    r = run_cli("train", "--config", str(REPO / "configs/wide_gen_block.yaml"), "--compare",
                str(paper), "--run-dir", str(tmp_path / "run"))  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "a policy of TileSuction, but this run trains BlockGrip" in r.stderr
    assert not (tmp_path / "run").exists()
