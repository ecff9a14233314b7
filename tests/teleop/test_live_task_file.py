"""``mimicrete teleop --task-file`` (issue 26 §1): the live server records in a researcher's task
spec (a bigger tile): the page's scene, the demo's ``/scene`` and its metadata are that spec's, the
hand log names it, and ``convert`` replays the hand log there to the same steps; a bad spec, or
one of another task than ``--task``, is one line and exit 2 before anything is served."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from mimicrete import _native, demos
from mimicrete.demonstrator.scene import TOOL_DOWN, hand_pose_for_tool0
from mimicrete.hands.layouts import to_layout
from mimicrete.hands.log import parse as read_handlog
from mimicrete.hands.model import GESTURE_SHAPES, hand_joints
from mimicrete.teleop import convert as cv
from mimicrete.teleop.live import Live
from mimicrete.teleop.protocol import WireFrame
from mimicrete.teleop.view import standing_calibration

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from _cli_run import run_cli  # noqa: E402

TILE = "half_extents = [0.075, 0.075, 0.005]"
BIG_TILE = "half_extents = [0.1, 0.1, 0.006]"


def big_tile_spec(tmp_path: Path) -> Path:
    text = _native.task_spec("TileSuction", as_toml=True)
    assert text.count(TILE) == 1
    path = tmp_path / "big_tile.toml"
    wide = ("object_x = [0.035, 0.285]", "object_x = [0.07, 0.285]")  # clear of the pad
    path.write_text(text.replace(TILE, BIG_TILE).replace(*wide))
    return path


def hand_toward(tool0: np.ndarray, t: float) -> np.ndarray:
    """WebXR joints (25, 3) of an open right hand that moves tool0 (pointing down) in a slow
    circle of 3 cm around ``tool0`` at time ``t`` (standing calibration)."""
    pose = np.eye(4)
    pose[:3, :3] = TOOL_DOWN
    pose[:3, 3] = tool0 + 0.03 * np.array([np.cos(t), np.sin(t), 0.0])
    rot, wrist = hand_pose_for_tool0(pose, "right", standing_calibration())
    openxr = hand_joints(GESTURE_SHAPES["opening"], rot, wrist, 1.0, "right")
    return to_layout(openxr[None], "webxr")[0]


def tile_size(entities: list[dict]) -> dict:
    return {e["id"]: e for e in entities}["tile"]["cubes"][0]["size"]


def test_a_live_episode_in_a_task_file_records_and_converts_there(tmp_path: Path) -> None:
    spec = big_tile_spec(tmp_path)
    spec.write_text(spec.read_text().replace('success = "installed"', 'success = "laid"'))
    out = tmp_path / "out"
    live = Live("suction", out, calibration=standing_calibration(), seed=4, task_file=str(spec))
    assert tile_size(live.scene) == {"x": 0.2, "y": 0.2, "z": 0.012}  # what the page draws
    live.start()
    tool0 = np.asarray(live.session.snapshot()["tool0"]["t"])
    for k in range(180):  # 2 s at 90 Hz
        t = k / 90.0
        live.push(WireFrame(k, t, 0.0, True, False, hand_toward(tool0, t), np.zeros((25, 3))))
    stopped = live.stop()
    live.close()
    assert live.success == "laid" and stopped["result"] in ("laid", "stopped")
    demo = out / "suction_0000.mcap"
    got = demos.read(demo)
    assert got["meta"]["task_file"] == str(spec)
    assert json.loads(got["meta"]["task_spec"])["object"]["half_extents"] == [0.1, 0.1, 0.006]
    from mcap.reader import make_reader

    with demo.open("rb") as f:
        first = next(make_reader(f).iter_messages(topics=["/scene"]))[2]
    assert tile_size(json.loads(first.data)["entities"]) == {"x": 0.2, "y": 0.2, "z": 0.012}
    log = read_handlog(out / "suction_0000.handlog.jsonl")
    assert log.header["extra"]["task_file"] == str(spec)
    recorded = json.loads(json.dumps(_native.load_task_spec(str(spec))))
    assert log.header["extra"]["task_spec"] == recorded
    # convert replays it in the same spec (the one the header names) to the same steps
    again = cv.convert_log(out / "suction_0000.handlog.jsonl", "suction", tmp_path / "conv.mcap")
    conv = demos.read(again.out)
    assert len(got["actions"]) > 20
    for key in ("obs", "actions", "rewards"):
        assert np.array_equal(conv[key], got[key]), key
    assert conv["meta"]["task_file"] == str(spec)


def test_teleop_refuses_a_bad_task_file_in_one_line(tmp_path: Path) -> None:
    spec = big_tile_spec(tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text(spec.read_text().replace("mass = 0.5 ", "mass = -2 "))
    for args, says in [
        (["--task-file", str(bad)], f"--task-file {bad}: object.mass = -2.0"),
        (["--task-file", str(tmp_path / "gone.toml")], f"--task-file {tmp_path / 'gone.toml'}"),
        (["--task-file", str(spec), "--task", "screw"],
         "runs the suction task (TileSuction), not --task screw"),
    ]:  # fmt: skip
        r = run_cli("teleop", *args, "--out", str(tmp_path / "o"), timeout=60)
        assert r.returncode == 2, (args, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
        assert lines[0].startswith("mimicrete teleop: error: ") and says in lines[0], lines[0]
