"""TileSuction on a UR5e and a UR10e (crates/tile-sim/tasks/tile_suction_ur5e.toml, ..._ur10e.toml)
through the real CLI: the scripted person's hand logs, converted through the teleop session,
install the tile, and the demos name the arm and draw it."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from _cli_run import run_cli  # noqa: E402

TASKS = Path(__file__).resolve().parents[1] / "crates" / "tile-sim" / "tasks"


@pytest.mark.parametrize("model", ["ur5e", "ur10e"])
def test_scripted_demos_install_on_the_arm_and_name_it(tmp_path: Path, model: str) -> None:
    from mcap.reader import make_reader

    spec = TASKS / f"tile_suction_{model}.toml"
    hands, demos = tmp_path / "hands", tmp_path / "demos"
    r = run_cli("synth-hands", "--task-file", str(spec), "--episodes", "3", "--seed", "0",
                "--out", str(hands))  # fmt: skip
    assert r.returncode == 0, r.stderr
    r = run_cli("convert", str(hands), "--task", "suction", "--out", str(demos))
    assert r.returncode == 0, r.stderr
    assert "3 installed (100.0 %)" in r.stdout, r.stdout
    for demo in sorted(demos.glob("*.mcap")):
        with demo.open("rb") as f:
            reader = make_reader(f)
            meta = {m.name: m.metadata for m in reader.iter_metadata()}
            assert meta["episode_start"]["robot_model"] == model
            for _, _, message in reader.iter_messages(topics=["/scene"]):
                ids = {e["id"] for e in json.loads(message.data)["entities"]}
                assert {"robot/upper_arm", "robot/wrist3", f"{model}_base"} <= ids, ids
                break
            else:
                raise AssertionError("no /scene")
    # demogen plays the arm's own kinematics: the UR3's would put every pose of a larger arm
    # somewhere else (or out of reach), and the new demos are of the arm they ran on
    gen = tmp_path / "gen"
    r = run_cli("demogen", "--demos", str(demos), "--count", "4", "--starts", "wide",
                "--out", str(gen), "--max-attempts", "4", "--no-progress")  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "yield 4/4" in r.stdout, r.stdout
    for demo in sorted(gen.glob("*.mcap")):
        with demo.open("rb") as f:
            meta = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
            assert meta["episode_start"]["robot_model"] == model
