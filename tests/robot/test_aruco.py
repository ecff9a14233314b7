"""--tile-pose aruco:CAMERA: the tile's pose from a marker in a camera's view (drawn through a
pinhole camera by _aruco_scene.py), refused when the marker is tilted or the view ambiguous,
stale when the camera stops; through the real CLI against the loopback controller."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from mimicrete.robot import deploy as dep
from mimicrete.robot.aruco import Calibration, MarkerPose, judge

from . import _aruco_scene as scene

sys.path.insert(0, str(Path(__file__).parent.parent))
from _cli_run import run_cli  # noqa: E402


@pytest.fixture
def marker(tmp_path):
    return MarkerPose(Calibration(scene.write_calibration(tmp_path / "cal.json")))


@pytest.mark.parametrize("pose", [(0.1, 0.32, 0.0), (0.2, 0.28, 0.4), (0.05, 0.36, -0.5)])
def test_the_tile_pose_from_the_marker(marker, pose):
    est, why = marker.estimate(scene.render(*pose))
    assert why == "ok"
    x, y, yaw = est
    assert math.hypot(x - pose[0], y - pose[1]) < 0.003  # 43 pixels of marker at 0.7 m
    assert abs(math.degrees(yaw - pose[2])) < 1.5


def test_a_tilted_marker_and_an_empty_view_are_refused(marker):
    est, why = marker.estimate(scene.render(0.1, 0.32, 0.0, tilt_deg=35))
    assert est is None and why.startswith("marker not lying flat (tilted 3")
    est, why = marker.estimate(np.full((480, 640), 128, np.uint8))
    assert est is None and why == "marker not seen"


def test_ambiguous_fits_are_refused_only_when_they_disagree():
    a = (0.10, 0.32, 0.0, 2.0)
    far = (0.11, 0.32, 0.0, 3.0)  # 1 cm away
    turned = (0.10, 0.32, math.radians(5), 3.0)
    near = (0.1005, 0.3202, 0.001, 4.0)  # the same tile
    assert judge([a, far], np.array([1.0, 1.2]))[1].startswith("ambiguous pose")
    assert judge([a, turned], np.array([1.0, 1.1]))[1].startswith("ambiguous pose")
    assert judge([a, far], np.array([0.2, 1.0])) == ((0.10, 0.32, 0.0), "ok")  # a clear winner
    assert judge([a, near], np.array([1.0, 1.05])) == ((0.10, 0.32, 0.0), "ok")
    # a tilted alternative is no alternative: the tile lies on the table
    assert judge([a, (0.2, 0.2, 1.0, 40.0)], np.array([1.0, 1.0]))[1] == "ok"


def test_shadow_with_a_camera_through_the_cli_until_the_camera_stops(run_dir, controller, tmp_path):
    tile = (0.1, 0.32, 0.0)
    video = scene.write_video(tmp_path / "cam.avi", [tile] * 25)  # 1 s at 25 fps, then it ends
    cal = scene.write_calibration(tmp_path / "cal.json")
    r = run_cli(
        "deploy", str(run_dir), "--robot", "ur3", "--shadow", "--host", controller.host,
        "--tile-pose", f"aruco:{video}", "--camera-calibration", str(cal), "--ticks", "200",
        "--out", str(tmp_path / "logs"),
    )  # fmt: skip
    assert r.returncode == 1, r.stderr
    assert f"stopped: tile pose: aruco:{video}: stale: no accepted marker pose for" in r.stdout
    (path,) = (tmp_path / "logs").glob("*.mcap")
    s = dep.summary(path)
    assert s["stop_kind"] == "tile_pose"
    assert 15 <= s["ticks"] <= 45  # the camera's second, then half a second of staleness
    assert s["tile_sources"] == {f"aruco:{video}": s["ticks"]}
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        ticks = [m.data for _, _, m in make_reader(f).iter_messages(["/deploy/tick"])]
    import json

    for t in map(json.loads, ticks):
        assert math.hypot(t["tile_pose"][0] - tile[0], t["tile_pose"][1] - tile[1]) < 0.003


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "--tile-pose aruco: needs --camera-calibration FILE.json"),
        (["--camera-calibration", "BAD"], "field 'base_from_camera' must be 4x4 finite numbers"),
        (["--camera-calibration", "CAL", "--tile-pose", "aruco:/no/such/video.avi"],
         "--tile-pose aruco:/no/such/video.avi: the camera does not open"),
        (["--camera-calibration", "CAL", "--tile-pose", "aruco:EMPTY"],
         "no accepted marker pose within 3 s (marker not seen)"),
    ],
)  # fmt: skip
def test_bad_camera_input_is_one_line_and_exit_2(run_dir, tmp_path, extra, message):
    import cv2

    cal = scene.write_calibration(tmp_path / "cal.json")
    bad = scene.write_calibration(tmp_path / "bad.json", base_from_camera=[[1, 0], [0, 1]])
    empty = tmp_path / "empty.avi"
    w = cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, scene.SIZE, False)
    for _ in range(5):
        w.write(np.full((480, 640), 128, np.uint8))
    w.release()
    subs = {"CAL": str(cal), "BAD": str(bad), "EMPTY": str(empty)}
    args = [subs.get(a, a.replace("EMPTY", str(empty))) for a in extra]
    tile = ["--tile-pose", "aruco:0"] if "--tile-pose" not in args else []
    r = run_cli("deploy", str(run_dir), "--robot", "ur3", "--sim", *tile, *args)
    assert r.returncode == 2, r.stdout + r.stderr
    assert message in r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr
