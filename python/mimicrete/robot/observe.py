"""The observation a TileSuction-layout policy was trained on, built from a robot's joint
angles and where the tile is.

tile-sim's frame (``crates/tile-sim/src/task/{mod,suction}.rs``): the six joint angles, the
suction command latched (+1 on, -1 off), the TCP (the cup lips' centre: tool0 by FK, then the
spec's ``tcp_z`` along its z axis), the target's centre (a tile lying on the pad) and the
tile's centre (Base frame, m): 16 floats. Five frames stacked, oldest first, the missing ones
zeros at the start. ``tests/robot/test_observe.py`` holds it equal to the simulator's own
observation along a policy's episode.

The tile: where the source says (lying on the table: its centre half its thickness above the
top), until the suction is on with the TCP within the spec's ``pick_dist`` of the tile's top
face: from then the tile is carried with the cups (``held``), as the simulator carries it, until
the suction is switched off (``released``: it stays where it was let go until the source reports
a new pose).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mimicrete import _native

FRAME_STACK = 5
FRAME_DIM = 16


class ObservationError(_native.MimicreteError, ValueError):
    pass


class Observer:
    def __init__(self, spec: dict[str, Any], target: Any) -> None:
        if spec["effector"]["kind"] != "suction" or "seal" in spec["effector"]:
            raise ObservationError(
                f"deploy builds the observation of TileSuction-layout tasks (a suction head, "
                f"{FRAME_DIM} floats a frame); this run's task {spec.get('name')!r} is not one"
            )
        action = spec["robot"].get("action") or "joint"
        if action != "joint":
            raise ObservationError(
                f"deploy drives policies whose actions are joint motions; this run's task "
                f"{spec.get('name')!r} moves the tool (robot.action = {action!r})"
            )
        self.model = str(spec["robot"]["model"])
        self.tcp_z = float(spec["effector"]["tcp_z"])
        self.top_z = float(spec["table"]["top_z"])
        self.half = float(spec["object"]["half_extents"][2])
        self.pick_dist = float(spec["thresholds"]["pick_dist"])
        self.target = np.asarray(target, np.float64)
        self.frames = np.zeros((FRAME_STACK, FRAME_DIM), np.float32)
        self.held = False
        self._offset = np.zeros(3)
        self._tile: np.ndarray | None = None  # last tile centre (m)
        self._released_at_version: int | None = None

    def tool0(self, q: np.ndarray) -> np.ndarray:
        return _native.kin_fk(np.asarray(q, np.float64), self.model)

    def tile_centre(
        self, T: np.ndarray, suction: bool, src_pose: tuple[float, float, float], version: int
    ) -> tuple[np.ndarray, str]:
        """The tile's centre this tick and where it came from (``source``, ``held``,
        ``released``)."""
        tcp = T[:3, 3] + T[:3, 2] * self.tcp_z
        R = T[:3, :3]
        from_source = np.array([src_pose[0], src_pose[1], self.top_z + self.half])
        if self.held and not suction:
            self.held = False
            self._released_at_version = version
        if not self.held and suction:
            tile = self._current(from_source, version)
            grasp = tile + np.array([0.0, 0.0, self.half])
            if np.linalg.norm(tcp - grasp) < self.pick_dist:
                self.held = True
                self._offset = R.T @ (tile - tcp)
        if self.held:
            carried = tcp + R @ self._offset
            self._tile = carried
            return carried, "held"
        tile = self._current(from_source, version)
        self._tile = tile
        return tile, ("released" if self._released_at_version is not None else "source")

    def _current(self, from_source: np.ndarray, version: int) -> np.ndarray:
        if self._released_at_version is not None:
            if version == self._released_at_version and self._tile is not None:
                return self._tile
            self._released_at_version = None
        return from_source

    def push(self, q: np.ndarray, suction: bool, tile: np.ndarray, T: np.ndarray) -> np.ndarray:
        """Add the newest frame; the stacked observation (FRAME_STACK * FRAME_DIM,) float32."""
        tcp = T[:3, 3] + T[:3, 2] * self.tcp_z
        f = np.concatenate([q, [1.0 if suction else -1.0], tcp, self.target, tile])
        self.frames[:-1] = self.frames[1:]
        self.frames[-1] = f.astype(np.float32)
        return self.frames.reshape(-1).copy()
