"""Still and moving right hands for a tool pose, in WebXR order: what the clutch's tests and
benchmark drive ``teleop.live.Live`` with (no browser), and the orientations a person uses."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from mimicrete.demonstrator.scene import TOOL_DOWN, hand_pose_for_tool0
from mimicrete.hands.layouts import to_layout
from mimicrete.hands.model import GESTURE_SHAPES, hand_joints
from mimicrete.kin import Calibration

RATE_HZ = 90.0
#: hand orientations a person uses, as turns of the tool-down hand (Base): about the vertical
#: (0, 90, 180, -90, 45 deg) and each tilted 0 or 30 deg; "palm down, fingers toward the robot"
#: among them
TURNS: list[Rotation] = [
    Rotation.from_euler("z", a, degrees=True) * Rotation.from_euler("x", b, degrees=True)
    for a in (0, 90, 180, -90, 45)
    for b in (0, 30)
]


def hand_for_tool(tool0: np.ndarray, turn: Rotation, calibration: Calibration) -> np.ndarray:
    """WebXR joints (25, 3) of an open right hand whose absolute mapping through
    ``calibration`` is tool0 at ``tool0`` (Base, m) turned by ``turn`` from pointing down."""
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = turn.as_matrix() @ TOOL_DOWN, tool0
    rot, wrist = hand_pose_for_tool0(pose, "right", calibration)
    openxr = hand_joints(GESTURE_SHAPES["opening"], rot, wrist, 1.0, "right")
    return to_layout(openxr[None], "webxr")[0]


class Driver:
    """Hand frames into a ``Live`` at 90 Hz (no left hand); keeps every step's reason for not
    following (None: it followed) and the hand-clock time of each step."""

    def __init__(self, live: Any) -> None:
        self.live, self.t, self.k = live, 0.0, 0
        self.why: list[str | None] = []
        self.step_t: list[float] = []

    def hold(self, joints: np.ndarray, seconds: float) -> None:
        self.move(joints, joints, seconds)

    def move(self, a: np.ndarray, b: np.ndarray, seconds: float) -> None:
        from mimicrete.teleop.protocol import WireFrame

        n = int(seconds * RATE_HZ)
        none = np.zeros_like(a)
        for i in range(n):
            u = i / max(n - 1, 1)
            f = WireFrame(self.k, self.t, 0.0, True, False, a + (b - a) * u, none)
            for s in self.live.push(f):
                self.why.append(s.why)
                self.step_t.append(self.t)
            self.t, self.k = self.t + 1 / RATE_HZ, self.k + 1

    def tool(self) -> np.ndarray:
        return np.asarray(self.live.session.snapshot()["tool0"]["t"])
