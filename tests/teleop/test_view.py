"""Where the page puts the robot cell: the scene is drawn through ``view_from_base`` (the inverse
of the calibration the server maps hands with), so the proposed standing calibration must put the
table top 0.8 m under the head and the workspace 0.5 m in front of it, and the tool at the hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mimicrete import kin
from mimicrete.teleop.session import Session
from mimicrete.teleop.view import (
    STANDING_BELOW,
    effector_state,
    standing_calibration,
    task_calibration,
    view_from_base,
)


def _local(calib: kin.Calibration, base_points: np.ndarray) -> np.ndarray:
    m = np.asarray(view_from_base(calib)).reshape(4, 4, order="F")
    p = np.c_[base_points, np.ones(len(base_points))]
    return (p @ m.T)[:, :3]


def test_standing_calibration_puts_the_table_low_and_the_workspace_ahead():
    calib = standing_calibration()
    # WebXR local: x right, y up, z back; the head at the origin
    for task in ("suction", "grip", "screw"):
        for seed in range(6):
            snap = Session(task, "webxr", "right", calib, seed).snapshot()
            pts = np.array([snap["object"]["t"], snap["target"]["t"]])
            local = _local(calib, pts)
            ahead, side = -local[:, 2], local[:, 0]
            assert np.all((ahead > 0.35) & (ahead < 0.65)), (task, local)
            assert np.all(np.abs(side) < 0.25), (task, local)
    table_top = _local(calib, np.array([[-0.035, 0.30, 0.0]]))[0]
    np.testing.assert_allclose(table_top, [0.0, -0.8, -0.5], atol=1e-12)
    # the hand maps back onto the same point: view_from_base is the calibration's inverse
    back = kin.points_to_base(table_top[None], calib)[0]
    np.testing.assert_allclose(back, [-0.035, 0.30, 0.0], atol=1e-12)


@pytest.mark.parametrize(("below", "ahead"), [(0.8, 0.5), (0.6, 0.4), (1.0, 0.7)])
def test_standing_calibration_parameters(below, ahead):
    c = standing_calibration(below=below, ahead=ahead, centre=(0.1, 0.2))
    got = _local(c, np.array([[0.1, 0.2, 0.0]]))[0]
    np.testing.assert_allclose(got, [0, -below, -ahead], atol=1e-12)
    assert np.linalg.det(c.rotation) == pytest.approx(1.0)


def test_effector_state_of_each_task():
    snap = Session("screw", "webxr", "right", standing_calibration(), 0).snapshot()
    ee = effector_state("screw", snap)
    assert ee == {"kind": "screw", "on": False, "spin": 0, "opening": pytest.approx(0.085)}
    assert effector_state("grip", snap)["opening"] == pytest.approx(0.085)
    row = Session("row", "webxr", "right", standing_calibration(), 0).snapshot()
    assert effector_state("row", row) == {"kind": "suction", "on": False}


TASKS = Path(__file__).resolve().parents[2] / "crates" / "tile-sim" / "tasks"


@pytest.mark.parametrize("model", ["ur5e", "ur10e"])
def test_a_larger_arms_spec_scales_the_standing_calibration(tmp_path, model):
    """``mimicrete teleop --task-file`` on a UR5e / UR10e spec: Live's default calibration is the
    standing one scaled by the spec's hand scale (the arm's workspace over the UR3's), so the
    scaled scene's tile and pad are drawn where the UR3's are, the table as far below the head."""
    from mimicrete import _native
    from mimicrete.teleop.live import Live

    spec = str(TASKS / f"tile_suction_{model}.toml")
    k = _native.hand_scale("suction", spec)
    dh = {m: _native.kin_dh(m) for m in ("ur3", model)}
    arm = [abs(d["a2"]) + abs(d["a3"]) for d in dh.values()]
    assert k == pytest.approx(arm[1] / arm[0], rel=1e-6) and k > 1.7
    live = Live("suction", tmp_path / "out", task_file=spec, seed=0)
    try:
        calib = live.calibration
        assert calib.scale == pytest.approx(k)
        std = standing_calibration()
        np.testing.assert_allclose(calib.translation, k * std.translation)
        for seed in range(4):
            snap = Session("suction", "webxr", "right", calib, seed, task_file=spec).snapshot()
            local = _local(calib, np.array([snap["object"]["t"], snap["target"]["t"]]))
            ahead, side = -local[:, 2], local[:, 0]
            assert np.all((ahead > 0.35) & (ahead < 0.65)), local
            assert np.all(np.abs(side) < 0.25), local
        table_top = _local(calib, np.array([[0.0, 0.0, 0.0]]))[0]
        assert table_top[1] == pytest.approx(-STANDING_BELOW)
    finally:
        live.close()


def test_the_ur3_tasks_keep_the_standing_calibration_bit_for_bit(tmp_path):
    from mimicrete import _native
    from mimicrete.teleop.live import Live

    spec = str(TASKS / "tile_suction.toml")
    assert _native.hand_scale("suction") == 1.0 == _native.hand_scale("suction", spec)
    assert "hand_scale" not in _native.load_task_spec(spec)["robot"]  # recorded specs as before
    std = standing_calibration().to_dict()
    for task_file in (None, spec):
        assert task_calibration("suction", task_file).to_dict() == std
        live = Live("suction", tmp_path / str(task_file is None), task_file=task_file)
        assert live.calibration.to_dict() == std
        live.close()


@pytest.mark.parametrize("model", ["ur3", "ur5e", "ur10e"])
def test_frame_poses_pose_the_arm_they_are_given(model):
    """``frame_poses(snapshot, model)`` poses the links of ``model``: on each spec's arm, the frames
    the simulator's own ``scene_frames()`` gives (its tool0 at the snapshot's tool0); the UR3's
    links at a larger arm's joints are elsewhere."""
    from mimicrete import _native
    from mimicrete.teleop.view import frame_poses

    spec = TASKS / ("tile_suction.toml" if model == "ur3" else f"tile_suction_{model}.toml")
    env = _native.SimEnv.from_spec_file(str(spec), 0)
    env.reset(3)
    snap = env.snapshot()
    frames = frame_poses(snap, model)
    assert frames.keys() == env.scene_frames().keys()
    for k, v in env.scene_frames().items():
        np.testing.assert_allclose(frames[k], v, atol=1e-9, err_msg=k)
    np.testing.assert_allclose(frames["tool0"][:3], snap["tool0"]["t"], atol=1e-9)
    if model != "ur3":
        ur3 = frame_poses(snap)
        assert np.linalg.norm(np.subtract(ur3["tool0"][:3], snap["tool0"]["t"])) > 0.1
