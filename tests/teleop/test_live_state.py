"""The state the live server sends after each frame (``Live.state``): the frames the scene's
entities are locked to, and why the arm does not follow, read off the session's newest control
step (it holds between steps and is forgotten with its session)."""

from __future__ import annotations

import numpy as np
import pytest

from mimicrete import _native
from mimicrete.demonstrator.scene import TOOL_DOWN, hand_pose_for_tool0
from mimicrete.hands.layouts import to_layout
from mimicrete.hands.model import GESTURE_SHAPES, hand_joints
from mimicrete.teleop.live import Live
from mimicrete.teleop.protocol import WireFrame
from mimicrete.teleop.view import standing_calibration

RATE_HZ = 90.0


def _hand_at(tool0_base: np.ndarray) -> np.ndarray:
    """WebXR joints (25, 3) of an open right hand that puts tool0 (pointing down) at
    ``tool0_base`` through the standing calibration."""
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = TOOL_DOWN, tool0_base
    rot, wrist = hand_pose_for_tool0(pose, "right", standing_calibration())
    openxr = hand_joints(GESTURE_SHAPES["opening"], rot, wrist, 1.0, "right")
    return to_layout(openxr[None], "webxr")[0]


def _push(live: Live, joints: np.ndarray, t0: float, seconds: float) -> float:
    """Push ``seconds`` of 90 Hz frames of a still right hand from ``t0``; the next frame's time."""
    n = int(seconds * RATE_HZ)
    for k in range(n):
        t = t0 + k / RATE_HZ
        live.push(WireFrame(k, t, 0.0, True, False, joints, np.zeros((25, 3))))
    return t0 + n / RATE_HZ


def test_why_comes_from_the_newest_step_of_the_current_session(tmp_path):
    live = Live("suction", tmp_path / "out", calibration=standing_calibration(), seed=11)
    assert live.last_step is None and live.state()["why"] == "no hand yet"
    tool0 = np.asarray(live.session.snapshot()["tool0"]["t"])
    t = _push(live, _hand_at(tool0), 0.0, 0.5)  # the clutch engages on the first frame
    assert live.state()["engaged"] and live.state()["why"] == "not recording"
    # the hand moves 0.8 m away: the tool walks toward it (2 cm a step) to the arm's reach
    far = _hand_at(tool0 + np.array([0.8, 0.0, 0.0]))
    t = _push(live, far, t, 2.0)
    state = live.state()
    assert state["hint"].startswith("out of the arm's reach")
    assert live.last_step is not None and live.last_step.why == "target unreachable"
    assert state["why"] == "target unreachable" and not state["following"]
    # a frame that runs no control step keeps the newest step's reason
    step = live.session.step_index
    live.push(WireFrame(0, t, 0.0, True, False, far, np.zeros((25, 3))))
    assert live.session.step_index == step
    assert live.state()["why"] == "target unreachable"
    # a new session (the recording) has no step yet: nothing of the preview's carries over
    live.start()
    assert live.last_step is None and live.state()["why"] == "no hand yet"
    tool0 = np.asarray(live.session.snapshot()["tool0"]["t"])
    _push(live, _hand_at(tool0), t, 1.0)
    state = live.state()
    assert live.last_step is not None and live.last_step.why is None
    assert state["why"] is None and state["following"] and state["recording"]
    live.discard()
    live.close()


@pytest.mark.parametrize("task", ["suction", "grip", "screw"])
def test_state_frames_pose_every_frame_of_the_scene(tmp_path, task):
    """Every frame an entity of the hello's scene is locked to (but ``base``, the identity) is
    posed in the state, as demo-log's ``scene_frames`` poses it from the joints and the object
    (its own pass down the chain; the session's comes from the step's shared one)."""
    live = Live(task, tmp_path / "out", calibration=standing_calibration(), seed=3)
    env = live.session.core
    rng = np.random.default_rng(0)
    for _ in range(5):
        env.set_joints(rng.uniform(-np.pi, np.pi, 6))
        frames = live.state()["frames"]
        used = {e["frame_id"] for e in env.scene_entities()} - {"base"}
        assert used <= set(frames)
        snap = env.snapshot()
        want = _native.scene_frames(snap["q"], [*snap["object"]["t"], *snap["object"]["q"]])
        assert set(frames) == set(want)
        for name, pose in want.items():
            np.testing.assert_allclose(frames[name], pose, atol=1e-12, err_msg=name)
    live.close()


@pytest.mark.parametrize("task", ["suction", "screw"])
def test_a_new_scene_goes_out_when_the_next_episode_moves_it(tmp_path, task):
    """The hello carries the current session's scene; a later session whose scene differs (the
    screw task's plate and bolt move with the seed; the suction task's table, pad and target do
    not) sends a ``scene`` message with its entities."""
    live = Live(task, tmp_path / "out", calibration=standing_calibration(), seed=0)
    assert live.scene == live.session.scene_entities()
    first = live.scene
    for _ in range(3):  # each stop saves the episode and previews the next seed
        live.start()
        live.stop()
    sent = [e["scene"] for e in live.events if e["type"] == "scene"]
    assert live.scene == live.session.scene_entities()
    if task == "suction":
        assert sent == [] and live.scene == first
    else:
        assert sent and sent[-1] == live.scene != first
        for scene in sent:
            bolt = next(e for e in scene if e["id"] == "bolt")
            assert bolt["frame_id"] == "base"
    live.close()
