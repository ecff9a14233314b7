"""The ``sim`` backend: the Rapier arm of a task (``mimicrete._native.SimEnv``) behind the robot
interface, for tests and rehearsal. A joint target becomes the simulator's action
(``clip((target - q) / joint_step, -1, 1)`` and the suction command), one env step per command;
the tile is wherever the simulator has it (``tile_pose()``). ``safety_mode`` and ``connected``
are plain attributes a test may change to script a fault."""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from mimicrete import _native

from . import NORMAL, RobotState


class SimRobot:
    backend = "sim"
    sends = True

    def __init__(
        self,
        task: str | None = None,
        task_file: str | None = None,
        seed: int = 0,
        tile_pose: tuple[float, float, float] | None = None,
    ) -> None:
        if task_file is not None:
            self.env = _native.SimEnv.from_spec_file(task_file, seed)
        else:
            self.env = _native.SimEnv(task or "TileSuction", seed)
        if tile_pose is not None:
            self.env.reset(seed, object_pose=list(tile_pose), target_offset=[0.0, 0.0])
        else:
            self.env.reset(seed)
        self.joint_step = float(self.env.joint_step)
        self.safety_mode = NORMAL
        self.connected = True
        self.suction = False
        self.t = 0.0
        self.ended: str | None = None  # the simulator's episode ended: installed / fell / truncated
        self.stopped: str | None = None
        self.commands: list[np.ndarray] = []

    def read(self) -> RobotState:
        s = self.env.snapshot()
        tcp = s["tcp"]
        rv = Rotation.from_quat(tcp["q"]).as_rotvec()
        return RobotState(
            q=np.asarray(s["q"], np.float64),
            tcp=np.concatenate([np.asarray(tcp["t"], np.float64), rv]),
            safety_mode=int(self.safety_mode),
            digital_out=int(bool(s["suction_on"])),
            digital_in=0,
            robot_time=self.t,
            connected=bool(self.connected),
            read_at=time.monotonic(),
        )

    def tile_pose(self) -> tuple[float, float, float]:
        o = self.env.snapshot()["object"]
        yaw = float(Rotation.from_quat(o["q"]).as_euler("xyz")[2])
        return float(o["t"][0]), float(o["t"][1]), yaw

    def snapshot(self) -> dict[str, Any]:
        return dict(self.env.snapshot())

    def set_joints(self, q: np.ndarray) -> None:
        """Teleport the arm (the live backend's recording sink drives the sim arm with this)."""
        self.env.set_joints(np.asarray(q, np.float64))
        self.t += 0.002

    def send_joint_target(self, q: np.ndarray, suction: bool) -> None:
        if self.stopped is not None:
            return
        q_now = np.asarray(self.env.snapshot()["q"], np.float64)
        a = np.clip((np.asarray(q, np.float64) - q_now) / self.joint_step, -1.0, 1.0)
        act = np.zeros(self.env.act_dim, np.float32)
        act[:6] = a
        act[6] = 1.0 if suction else -1.0
        self.suction = bool(suction)
        self.commands.append(np.asarray(q, np.float64).copy())
        _, _, terminated, truncated, info = self.env.step(act)
        self.t += 0.04
        if terminated or truncated:
            self.ended = (
                "installed"
                if info.get("installed")
                else "fell"
                if info.get("fell")
                else "truncated"
                if truncated
                else "terminated"
            )

    def stop(self, reason: str) -> None:
        if self.stopped is None:
            self.stopped = reason

    def close(self) -> None:
        pass
