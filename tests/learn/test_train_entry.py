"""`python train.py` on a fresh checkout (configs and train.py, no demos): it makes the demos the
way `make demos` does, says so, and trains (issue 12: it stopped with "demo path demos/suction
does not exist")."""

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
    "--set", "behavior.reward_signals.gail.network_settings.hidden_units=32",
    "--set", "behavior.behavioral_cloning.pretrain_steps=5",
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
    assert "demos: demos/suction has 0 episodes, making 60" in r.stdout
    assert len(list((tmp_path / "demos/suction").glob("*.mcap"))) == 60
    run = tmp_path / "runs/group3-seed0"
    assert json.loads((run / "run.json").read_text())["demos"] == "demos/suction"
    assert json.loads((run / "eval.json").read_text())["episodes"] == 2
    assert json.loads((run / "eval_wide.json").read_text())["starts"] == "wide"
    assert "group3-seed0, wide starts" in r.stdout and "paper, group 3 (Table 5)" in r.stdout
    assert "trained 1024 steps" in r.stdout
    # the hand logs are the ones `make demos` writes (synth-hands --episodes 60 --seed 0)
    from mimicrete import cli

    assert cli.main(["synth-hands", "--task", "suction", "--episodes", "60", "--seed", "0",
                     "--out", str(tmp_path / "make_demos")]) == 0  # fmt: skip
    made = sorted((tmp_path / "data/hands/suction").iterdir())
    assert [p.name for p in made] == sorted(p.name for p in (tmp_path / "make_demos").iterdir())
    assert all(p.read_bytes() == (tmp_path / "make_demos" / p.name).read_bytes() for p in made)
    # a second `python train.py` finds the demos (and the run) and does not make them again
    r2 = subprocess.run(
        [sys.executable, "train.py", *SMALL, "--force"],
        cwd=tmp_path, capture_output=True, text=True, env=env, timeout=1800,
    )  # fmt: skip
    assert r2.returncode == 0, r2.stderr[-3000:]
    assert "making" not in r2.stdout
