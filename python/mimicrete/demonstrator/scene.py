"""The scripted demonstrator's view of a task: where the object, the target and the tool are
(read from the simulator), and the inverse of ur3-kin's hand → tool0 map (which hand pose puts
the tool where the person wants it)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mimicrete import kin, tasks

HAND_RATE_HZ = 90.0

#: Gesture class (paper Table 1) → finger shape shown.
SHAPE_OF: dict[str, str] = {
    "closing": "closing",
    "opening": "opening",
    "fixed": "fixed",
    "closing_fixed": "closing",
    "closing_tightening": "tightening",
    "closing_loosening": "loosening",
    "opening_stopped": "opening",
    "fixed_stopped": "fixed",
}

#: Columns are tool0's axes in hand-frame coordinates (ur3_kin ``tool_from_hand_rotation``).
TOOL_FROM_HAND = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: tool0 pointing straight down, tool X along Base X (tile-sim ``expert::tool_down``).
TOOL_DOWN = np.diag([1.0, -1.0, -1.0])


# ----------------------------------------------------------------------------------------------
# Inverting ur3-kin's hand → tool0 map (the forward map is mimicrete.kin.hand_to_target)
# ----------------------------------------------------------------------------------------------


def _affine(calib: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(A (3, 3), b (3,))`` with ``p_base = A · p + b``, read off ur3-kin's own point map
    (:func:`mimicrete.kin.points_to_base`) so that axis conventions live only in the crate."""
    pts = kin.points_to_base(np.vstack([np.zeros(3), np.eye(3)]), calib)
    return (pts[1:] - pts[0]).T, pts[0]


def points_from_base(points: np.ndarray, calib: Any) -> np.ndarray:
    """Base points ``(..., 3)`` → the calibration's (headset) space: the inverse of
    :func:`mimicrete.kin.points_to_base`."""
    a, b = _affine(calib)
    return (np.asarray(points, dtype=np.float64) - b) @ np.linalg.inv(a).T


def hand_pose_for_tool0(
    tool0: np.ndarray, handedness: str, calib: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Invert :func:`mimicrete.kin.hand_to_target`: the hand-model wrist rotation (columns: the
    hand frame of :mod:`mimicrete.hands.model` in headset space) and wrist position that give
    ``tool0`` (``(4, 4)`` or a batch ``(n, 4, 4)`` → ``(…, 3, 3)``, ``(…, 3)``)."""
    tool0 = np.asarray(tool0, dtype=np.float64)
    r_hand_base = tool0[..., :3, :3] @ TOOL_FROM_HAND.T
    # ur3-kin negates x' for a left hand: its frame is ours · diag(-1, 1, -1)
    if handedness == "left":
        r_hand_base = r_hand_base @ np.diag([-1.0, 1.0, -1.0])
    a, _ = _affine(calib)
    rot_base_from_space = a / np.linalg.norm(a[:, 0])  # a = scale · rotation
    return rot_base_from_space.T @ r_hand_base, points_from_base(tool0[..., :3, 3], calib)


def _rot_batch(axis: int, angle: np.ndarray) -> np.ndarray:
    """Rotations ``(n, 3, 3)`` about coordinate axis ``axis`` (0 x, 1 y, 2 z)."""
    c, s = np.cos(angle), np.sin(angle)
    r = np.zeros((len(angle), 3, 3))
    i, k = [(1, 2), (2, 0), (0, 1)][axis]
    r[:, axis, axis] = 1.0
    r[:, i, i] = c
    r[:, k, k] = c
    r[:, i, k] = -s
    r[:, k, i] = s
    return r


# ----------------------------------------------------------------------------------------------
# Scene: the one place positions come from
# ----------------------------------------------------------------------------------------------


@dataclass
class Scene:
    """What the demonstrator sees at the start of an episode (Base frame, metres).

    Attributes:
        task: ``suction``, ``grip``, ``screw`` or ``row``.
        episode_seed: the simulator seed of the episode.
        tcp: the end effector's TCP (cup centre / between the fingertips).
        tcp_z: distance from tool0 (flange) to the TCP along the tool axis.
        object: centre of the tile / block / nut (the row: its first tile).
        target: where the object's centre must end up.
        objects: the row's tiles' centres ``(n, 3)``, in row order (``None`` for one object).
        targets: where each of the row's tiles must end up ``(n, 3)`` (tile ``i`` on pad ``i``).
        object_yaw: how the object is turned about Base Z (rad; the tile's edges, which a
            person squares the suction head to where the task asks for it, ``place``).
        target_yaw: how the target is turned about Base Z (rad; the pad's edges).
    """

    task: str
    episode_seed: int
    tcp: np.ndarray
    tcp_z: float
    object: np.ndarray
    target: np.ndarray
    objects: np.ndarray | None = None
    targets: np.ndarray | None = None
    object_yaw: float = 0.0
    target_yaw: float = 0.0

    def picks(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The (object, target) pairs to carry, in the order a person does them: the row's
        tiles one after another, else the one object."""
        if self.objects is None or self.targets is None:
            return [(self.object, self.target)]
        return list(zip(self.objects, self.targets, strict=True))

    def to_dict(self) -> dict[str, Any]:
        d = {
            "task": self.task,
            "episode_seed": self.episode_seed,
            "tcp": np.round(self.tcp, 6).tolist(),
            "tcp_z": round(self.tcp_z, 6),
            "object": np.round(self.object, 6).tolist(),
            "target": np.round(self.target, 6).tolist(),
        }
        if self.objects is not None and self.targets is not None:
            d["objects"] = np.round(self.objects, 6).tolist()
            d["targets"] = np.round(self.targets, 6).tolist()
        # a turned object or target only (the paper's starts turn neither: their logs' headers
        # stay as they were before the yaws were seen)
        if self.object_yaw or self.target_yaw:
            d["object_yaw"] = round(self.object_yaw, 6)
            d["target_yaw"] = round(self.target_yaw, 6)
        return d


def obs_layout(task: str) -> dict[str, slice]:
    """Fields of one observation frame (tile-sim ``Task::obs_frame_dim``)."""
    if task == "screw":
        return {
            "q": slice(0, 6),
            "tcp": slice(8, 11),
            "target": slice(11, 14),
            "object": slice(14, 17),
        }
    return {"q": slice(0, 6), "tcp": slice(7, 10), "target": slice(10, 13), "object": slice(13, 16)}


def scene_from_obs(
    task: str, seed: int, obs: np.ndarray, frame_dim: int, model: str = "ur3"
) -> Scene:
    """Read a :class:`Scene` from a reset observation (newest frame last) of an env whose arm is
    ``model``."""
    from mimicrete import kin

    f = np.asarray(obs, dtype=np.float64).reshape(-1)[-frame_dim:]
    lay = obs_layout(task)
    tcp = f[lay["tcp"]]
    tool0 = kin.fk(f[lay["q"]], model=model)
    return Scene(
        task,
        int(seed),
        tcp,
        float(np.linalg.norm(tool0[:3, 3] - tcp)),
        f[lay["object"]],
        f[lay["target"]],
    )


def yaw_of(quat: Any) -> float:
    """The yaw about Base Z (rad) of a body whose orientation is the quaternion ``quat``
    (``x, y, z, w``): the angle of its x axis in the Base x-y plane."""
    r = kin.quat_matrix(quat)
    return float(np.arctan2(r[1, 0], r[0, 0]))


def square_turn(yaw_from: float, yaw_to: float) -> float:
    """The least turn (rad, in ``[-45°, 45°)``) that takes a square thing at ``yaw_from`` to lie
    square to one at ``yaw_to`` (their edges parallel; tile-sim's ``expert::square_to``): a
    square tile, or the suction head, whose four cups repeat every 90°."""
    q = 0.5 * np.pi
    return float((yaw_to - yaw_from + 0.5 * q) % q - 0.5 * q)


def have_simulator() -> bool:
    """Whether ``mimicrete._native`` was built with the simulator (``tile-sim``) bindings."""
    from mimicrete import _native

    return hasattr(_native, "SimEnv")


def scene_from_env(task: str, seed: int, task_file: str | None = None) -> Scene:
    """The scene of episode ``seed`` as the simulator resets it (the one switch for where the
    demonstrator's knowledge comes from): positions of the end effector, the object and the
    target, which a person sees in the VR scene. ``task_file``: the task spec file whose env
    is reset (its starts, object and target), instead of ``task``'s built-in one."""
    from mimicrete import _native

    if not have_simulator():
        raise RuntimeError(
            "mimicrete._native was built without the simulator bindings (tile-sim); "
            "rebuild with `make native`"
        )
    if task_file is not None:
        env = _native.SimEnv.from_spec_file(task_file, 0)
    else:
        env = _native.SimEnv(tasks.get(task).sim)
    env.reset(int(seed))
    snap = env.snapshot()
    tcp = np.array(snap["tcp"]["t"], dtype=np.float64)
    tool0 = np.array(snap["tool0"]["t"], dtype=np.float64)
    row = snap.get("row") or []
    return Scene(
        task,
        int(seed),
        tcp,
        float(np.linalg.norm(tool0 - tcp)),
        np.array(snap["object"]["t"], dtype=np.float64),
        np.array(snap["target"]["t"], dtype=np.float64),
        np.array([r["object"]["t"] for r in row], dtype=np.float64) if row else None,
        np.array([r["target"]["t"] for r in row], dtype=np.float64) if row else None,
        yaw_of(snap["object"]["q"]),
        yaw_of(snap["target"]["q"]),
    )
