"""The state the live server sends after each frame (``Live.state``): the frames the scene's
entities are locked to."""

from __future__ import annotations

import numpy as np
import pytest

from mimicrete.teleop.live import Live
from mimicrete.teleop.view import standing_calibration


@pytest.mark.parametrize("task", ["suction", "grip", "screw"])
def test_state_frames_pose_every_frame_of_the_scene(tmp_path, task):
    """Every frame an entity of the hello's scene is locked to (but ``base``, the identity) is
    posed in the state, as the simulator's own ``scene_frames`` poses it."""
    live = Live(task, tmp_path / "out", calibration=standing_calibration(), seed=3)
    env = live.session.env
    rng = np.random.default_rng(0)
    for _ in range(5):
        env.set_joints(rng.uniform(-np.pi, np.pi, 6))
        frames = live.state()["frames"]
        used = {e["frame_id"] for e in env.scene_entities()} - {"base"}
        assert used <= set(frames)
        want = env.scene_frames()
        assert set(frames) == set(want)
        for name, pose in want.items():
            np.testing.assert_allclose(frames[name], pose, atol=1e-12, err_msg=name)
    live.close()
