"""TileSuction on a UR5e and a UR10e (crates/tile-sim/tasks/tile_suction_ur5e.toml, ..._ur10e.toml)
through the real CLI: the scripted person's hand logs, converted through the teleop session,
install the tile, and the demos name the arm and draw it."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
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


def _arm_ratio(model: str) -> float:
    """The arm's upper arm and forearm (|a2| + |a3|, ur3-kin's DH table) over the UR3's."""
    from mimicrete import _native

    def length(m: str) -> float:
        dh = _native.kin_dh(m)
        return abs(dh["a2"]) + abs(dh["a3"])

    return length(model) / length("ur3")


def _synth(tmp_path: Path, spec: Path, episodes: int = 2) -> list:
    from mimicrete.hands.log import parse as read_handlog

    out = tmp_path / spec.stem
    r = run_cli("synth-hands", "--task-file", str(spec), "--episodes", str(episodes),
                "--seed", "0", "--out", str(out))  # fmt: skip
    assert r.returncode == 0, r.stderr
    return [read_handlog(p) for p in sorted(out.glob("*.handlog.jsonl"))]


def _horizontal_extent(logs: list) -> np.ndarray:
    """The span (m) of the hands' centroids over the logs along OpenXR x (right) and z (back),
    the horizontal plane of the headset's space: where the person's hand went on the table."""
    pts = np.concatenate([np.asarray(log.joints).mean(axis=1) for log in logs])
    return np.ptp(pts[:, [0, 2]], axis=0)


@pytest.mark.parametrize("model", ["ur5e", "ur10e"])
def test_synth_hands_move_at_human_scale_on_a_larger_arm(tmp_path: Path, model: str) -> None:
    """The hand scale comes from the spec's arm (tile-sim's workspace_scale, through
    ``_native.hand_scale``): the recorded calibration's scale is the arm's |a2| + |a3| over the
    UR3's, and the person's hand covers about the UR3 task's distances, not ``scale`` times them
    (the layout is the UR3's x 1.6 / x 2.2, a bit less than the arm ratio 1.79 / 2.59)."""
    from mimicrete import _native
    from mimicrete.kin import Calibration

    k = _arm_ratio(model)
    assert k == pytest.approx({"ur5e": 1.789, "ur10e": 2.592}[model], abs=1e-3)
    spec = TASKS / f"tile_suction_{model}.toml"
    assert _native.hand_scale("suction", str(spec)) == pytest.approx(k)
    ur3 = _synth(tmp_path, TASKS / "tile_suction.toml")
    big = _synth(tmp_path, spec)
    c = big[0].header["extra"]["calibration"]
    assert c["scale"] == pytest.approx(k, rel=1e-6)
    default = Calibration()
    np.testing.assert_allclose(c["translation"], k * default.translation, rtol=1e-6)
    np.testing.assert_array_equal(c["rotation"], default.rotation)
    # the UR3 spec's logs are at ur3-kin's default calibration, scale 1, as before
    assert ur3[0].header["extra"]["calibration"] == default.to_dict()
    ratio = _horizontal_extent(big) / _horizontal_extent(ur3)
    layout = {"ur5e": 1.6, "ur10e": 2.2}[model]
    # about the UR3's extent (layout / k: 0.89, 0.85), far from the unscaled layout x
    assert np.all((ratio > 0.7) & (ratio < 1.15)), (ratio, layout / k)
    unscaled = _horizontal_extent(big) * k / _horizontal_extent(ur3)
    assert np.all(unscaled > 1.4), unscaled


def test_a_ur3_task_file_synthesises_the_built_in_tasks_hands(tmp_path: Path) -> None:
    """Scale 1 on the UR3: a UR3 spec file's hand logs are the built-in task's frame for frame."""
    from mimicrete.hands.log import parse as read_handlog

    spec = _synth(tmp_path, TASKS / "tile_suction.toml")
    out = tmp_path / "builtin"
    r = run_cli("synth-hands", "--task", "suction", "--episodes", "2", "--seed", "0",
                "--out", str(out))  # fmt: skip
    assert r.returncode == 0, r.stderr
    builtin = [read_handlog(p) for p in sorted(out.glob("*.handlog.jsonl"))]
    assert len(spec) == len(builtin) == 2
    for a, b in zip(spec, builtin, strict=True):
        assert a.header["extra"]["calibration"] == b.header["extra"]["calibration"]
        assert a.joints.tobytes() == b.joints.tobytes()


def test_a_specs_hand_scale_overrides_the_arms(tmp_path: Path) -> None:
    """``robot.hand_scale = 2.2`` (the UR10e layout's own scale) is the scale the hand logs record;
    0 is refused in one line naming the field."""
    text = (TASKS / "tile_suction_ur10e.toml").read_text()
    assert text.count('model = "ur10e"\n') == 1
    spec = tmp_path / "ur10e_2.2.toml"
    spec.write_text(text.replace('model = "ur10e"\n', 'model = "ur10e"\nhand_scale = 2.2\n'))
    (log,) = _synth(tmp_path, spec, episodes=1)
    assert log.header["extra"]["calibration"]["scale"] == pytest.approx(2.2)
    assert log.header["extra"]["task_spec"]["robot"]["hand_scale"] == pytest.approx(2.2)
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('model = "ur10e"\n', 'model = "ur10e"\nhand_scale = 0\n'))
    r = run_cli("synth-hands", "--task-file", str(bad), "--episodes", "1", "--out", str(tmp_path))
    assert r.returncode == 2, r.stderr
    line = r.stderr.strip().splitlines()
    assert len(line) == 1 and "robot.hand_scale = 0.0" in line[0] and "> 0" in line[0], line
