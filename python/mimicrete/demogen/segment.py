"""Object-centric segments of a recorded demo and their transform to a new start (MimicGen).

A TileSuction demo has two subtasks split at the effector switch (the step whose recorded command
turns the suction on): **approach + grasp**, relative to the tile's pose at the episode start,
and **transport + place**, relative to the target's pose. Each segment is the sequence of tool0
(flange) poses the arm reached, one per recorded action: the pose after action ``k`` is forward
kinematics of the joints in observation ``k + 1`` (the last action's, of the joints the arm was
commanded to, the observation after the end not being recorded).

For a new start, :func:`transform_poses` moves every pose of a segment rigidly with its frame:
``T_new · T_src⁻¹ · P``. Frames are ``(x, y, z, yaw)`` about Base Z. By default the generator
keeps the source's yaw (``rotate=False``): tile-sim's pick and install are judged on the tile's
centre alone, and the tile's yaw is not in the observation, so turning the tool with the tile
would make the recorded actions depend on something the policy cannot see.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import _native, kin
from mimicrete._native import MimicreteError
from mimicrete.demonstrator.scene import obs_layout

TASK = "TileSuction"
FRAME_DIM = 16
_LAY = obs_layout("suction")


class DemoGenError(MimicreteError, ValueError):
    """A source demo that cannot be segmented, or bad generation input (names the problem)."""


def frame(x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
    """A ``(4, 4)`` frame at ``(x, y, z)`` turned by ``yaw`` (rad) about Base Z."""
    c, s = np.cos(yaw), np.sin(yaw)
    f = np.eye(4)
    f[:2, :2] = [[c, -s], [s, c]]
    f[:3, 3] = [x, y, z]
    return f


def transform_poses(poses: np.ndarray, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Poses ``(n, 4, 4)`` expressed in frame ``src`` carried to the same relative place in
    ``dst``: ``dst · src⁻¹ · P``."""
    rel = dst @ np.linalg.inv(src)
    return np.einsum("ij,njk->nik", rel, np.asarray(poses, dtype=np.float64))


@dataclass
class Segment:
    """One object-centric subtask of a source demo.

    ``poses`` (n, 4, 4): tool0 after each of its actions; ``commands`` (n,): the recorded
    end-effector command of each; ``relative_to``: ``"object"`` or ``"target"``; ``src``: the
    frame it was recorded in (4, 4)."""

    poses: np.ndarray
    commands: np.ndarray
    relative_to: str
    src: np.ndarray

    def __len__(self) -> int:
        return len(self.poses)

    def moved_to(self, dst: np.ndarray) -> np.ndarray:
        """This segment's poses in frame ``dst`` (:func:`transform_poses`)."""
        return transform_poses(self.poses, self.src, dst)


@dataclass
class SourceDemo:
    """A recorded TileSuction demo split into its two segments."""

    name: str
    tile: np.ndarray  # (3,) tile centre at the start
    target: np.ndarray  # (3,) target at the start
    segments: list[Segment] = field(default_factory=list)
    meta: dict[str, str] = field(default_factory=dict)

    @property
    def length(self) -> int:
        return sum(len(s) for s in self.segments)


def _newest(obs: np.ndarray) -> np.ndarray:
    return np.asarray(obs, np.float64).reshape(len(obs), -1)[:, -FRAME_DIM:]


def segment_episode(
    obs: np.ndarray, actions: np.ndarray, name: str = "demo", meta: dict[str, str] | None = None
) -> SourceDemo:
    """Split one recorded episode (obs ``(T, 80)``, actions ``(T, 7)``) at its effector switch."""
    obs, actions = np.asarray(obs), np.asarray(actions)
    if obs.ndim != 2 or obs.shape[1] != 5 * FRAME_DIM or actions.shape != (len(obs), 7):
        raise DemoGenError(
            f"{name}: not a TileSuction demo (obs {obs.shape}, actions "
            f"{actions.shape}; expected (T, 80) and (T, 7))"
        )
    f = _newest(obs)
    on = np.flatnonzero(actions[:, 6] >= 0.5)
    if len(on) == 0:
        raise DemoGenError(f"{name}: the suction is never switched on; nothing to segment")
    k = int(on[0])
    if k < 2 or k > len(obs) - 3:
        raise DemoGenError(
            f"{name}: the suction switches on at step {k} of {len(obs)}; a segment would be empty"
        )
    q_after = np.vstack([f[1:, _LAY["q"]], f[-1:, _LAY["q"]] + actions[-1:, :6] * 0.04])
    poses = kin.fk_batch(q_after, model="ur3")
    tile, target = f[0, _LAY["object"]], f[0, _LAY["target"]]
    cmds = actions[:, 6].astype(np.float64)
    segs = [
        Segment(poses[:k], cmds[:k], "object", frame(*tile)),
        Segment(poses[k:], cmds[k:], "target", frame(*target)),
    ]
    return SourceDemo(name, tile.copy(), target.copy(), segs, dict(meta or {}))


def load_sources(path: str | Path, count: int | None = None) -> list[SourceDemo]:
    """The first ``count`` (all: None) MCAP demos of a file or directory, segmented. Only
    installing TileSuction demos are used (a failed one is no source)."""
    path = Path(path)
    if not path.exists():
        raise DemoGenError(f"--demos {path}: no such file or directory")
    files = [Path(p) for p in _native.demo_files(str(path))]
    if not files:
        raise DemoGenError(f"--demos {path}: no *.mcap demos in it")
    out = []
    for p in files:
        if count is not None and len(out) >= count:
            break
        d: Any = _native.demo_read(str(p))
        meta = dict(d["meta"])
        if meta.get("task", TASK) != TASK:
            raise DemoGenError(f"{p}: a {meta.get('task')} demo; demogen handles {TASK}")
        if meta.get("success") == "false":
            continue
        out.append(segment_episode(d["obs"], d["actions"], p.name, meta))
    if not out:
        raise DemoGenError(f"--demos {path}: no installing demo to generate from")
    return out
