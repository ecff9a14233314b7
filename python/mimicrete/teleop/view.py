"""What the live page draws: the simulator's scene as Foxglove ``SceneEntity`` JSON, and the poses
of the frames those entities are locked to.

The geometry comes from tile-sim (``SimEnv.scene()``: the table, the robot's links, the end
effector, the pad, the target and the object, each in a named frame) and the poses from its
snapshot (``links`` 0-6 = Base … tool0, ``object``, ``tool0``), so the page shows exactly the
world that is simulated.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mimicrete import kin
from mimicrete.kin import Calibration


def _pose(t: Any, q: Any) -> dict[str, Any]:
    return {
        "position": dict(zip("xyz", map(float, t), strict=True)),
        "orientation": dict(zip("xyzw", map(float, q), strict=True)),
    }


def _color(rgba: Any) -> dict[str, float]:
    return dict(zip("rgba", map(float, rgba), strict=True))


def _quat_z_to(v: np.ndarray) -> list[float]:
    """Quaternion (x, y, z, w) turning +Z onto the unit vector ``v``."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(np.dot(z, v))
    if c < -0.999999:
        return [1.0, 0.0, 0.0, 0.0]
    axis = np.cross(z, v)
    q = np.array([axis[0], axis[1], axis[2], 1.0 + c])
    return (q / np.linalg.norm(q)).tolist()


def _frame_id(frame: str) -> str:
    return "base" if frame == "world" else frame


def scene_entities(items: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """tile-sim scene items → Foxglove ``SceneEntity`` objects (one per item; a capsule is a
    cylinder between its end points with a sphere at each end)."""
    out = []
    for i, it in enumerate(items):
        ent: dict[str, Any] = {
            "id": f"{it['name']}#{i}",
            "frame_id": _frame_id(it["frame"]),
            "cubes": [],
            "cylinders": [],
            "spheres": [],
        }
        color = _color(it["rgba"])
        kind = it["kind"]
        if kind == "box":
            size = [2.0 * float(h) for h in it["half_extents"]]
            ent["cubes"].append(
                {
                    "pose": _pose(it["translation"], it["rotation"]),
                    "size": dict(zip("xyz", size, strict=True)),
                    "color": color,
                }
            )
        elif kind == "cylinder":
            d, h = 2.0 * float(it["radius"]), 2.0 * float(it["half_height"])
            ent["cylinders"].append(
                {
                    "pose": _pose(it["translation"], it["rotation"]),
                    "size": {"x": d, "y": d, "z": h},
                    "bottom_scale": 1.0,
                    "top_scale": 1.0,
                    "color": color,
                }
            )
        elif kind == "capsule":
            a, b = np.asarray(it["a"], float), np.asarray(it["b"], float)
            off = np.asarray(it["translation"], float)
            a, b = a + off, b + off
            d = 2.0 * float(it["radius"])
            axis = b - a
            length = float(np.linalg.norm(axis))
            if length > 1e-9:
                ent["cylinders"].append(
                    {
                        "pose": _pose((a + b) / 2.0, _quat_z_to(axis / length)),
                        "size": {"x": d, "y": d, "z": length},
                        "bottom_scale": 1.0,
                        "top_scale": 1.0,
                        "color": color,
                    }
                )
            for p in (a, b):
                ent["spheres"].append(
                    {
                        "pose": _pose(p, [0, 0, 0, 1]),
                        "size": {"x": d, "y": d, "z": d},
                        "color": color,
                    }
                )
        out.append(ent)
    return out


def frame_poses(snap: dict[str, Any]) -> dict[str, list[float]]:
    """``{frame_id: [x, y, z, qx, qy, qz, qw]}`` in Base for every frame the scene uses."""
    frames = {"base": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]}
    for i, p in enumerate(snap["links"]):
        frames[f"link{i}"] = [*map(float, p["t"]), *map(float, p["q"])]
    for name in ("object", "tool0", "tcp", "target"):
        p = snap[name]
        frames[name] = [*map(float, p["t"]), *map(float, p["q"])]
    return frames


def effector_state(task: str, snap: dict[str, Any]) -> dict[str, Any]:
    """The end effector's state for the HUD and the drawing."""
    if task == "suction":
        return {"kind": "suction", "on": bool(snap["suction_on"])}
    if task == "grip":
        return {"kind": "gripper", "opening": float(snap["gripper_width"])}
    # the screw task's tool is the gripper too: its fingers close on the nut
    return {
        "kind": "screw",
        "on": bool(snap["held"]),
        "spin": int(snap["spin"]),
        "opening": float(snap["gripper_width"]),
    }


#: Where a standing user works (metres): the table top :data:`STANDING_BELOW` under the head
#: and the workspace's centre :data:`STANDING_AHEAD` in front of it.
STANDING_BELOW = 0.8
STANDING_AHEAD = 0.5
#: The middle of the tasks' workspace in Base (x, y), m: between the pad (-0.22, 0.28) and the
#: tile's start strip (x 0 … 0.15, y 0.32) of tile-sim's suction and grip scenes.
WORKSPACE_CENTRE = (-0.035, 0.30)


def standing_calibration(
    below: float = STANDING_BELOW,
    ahead: float = STANDING_AHEAD,
    centre: tuple[float, float] = WORKSPACE_CENTRE,
) -> Calibration:
    """A calibration for a standing user at the table's +Y edge facing the robot (−Y in Base):
    the ``local`` origin (the head when the session began) is ``below`` m above the table top
    (Base z = 0) and ``ahead`` m behind the workspace's ``centre``, looking at it. The page draws
    the scene with the inverse of the calibration (:func:`view_from_base`), so the robot's tool
    is drawn at the hand and the workspace sits in front of the user at a standing table's height.

    ur3-kin's default calibration (operator at the robot's base facing +X, head 0.6 m above the
    table) puts the pad 0.12 m *behind* the head and the tile 0.3 m to the left.
    """
    # rotation columns: where forward, left and up (FLU) point in Base
    rotation = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    translation = np.array([centre[0], centre[1] + ahead, below])
    return Calibration(rotation, translation, 1.0, Calibration().space)


def view_from_base(calibration: Calibration) -> list[float]:
    """The 4×4 (column-major) from Base into the tracking space: the inverse of the calibration's
    affine map, read off ur3-kin's ``points_to_base`` (so the axis change lives in one place)."""
    basis = np.vstack([np.zeros(3), np.eye(3)])
    p = kin.points_to_base(basis, calibration)
    m = np.eye(4)
    m[:3, :3] = (p[1:] - p[0]).T  # columns: images of the unit vectors
    m[:3, 3] = p[0]
    return np.linalg.inv(m).reshape(-1, order="F").tolist()


def quat_xyzw(r: np.ndarray) -> list[float]:
    """Unit quaternion ``[x, y, z, w]`` of a rotation matrix (Shepperd's method, closed form)."""
    t = float(r[0, 0] + r[1, 1] + r[2, 2])
    if t > 0.0:
        k = 2.0 * np.sqrt(t + 1.0)
        q = [(r[2, 1] - r[1, 2]) / k, (r[0, 2] - r[2, 0]) / k, (r[1, 0] - r[0, 1]) / k, k / 4.0]
    else:
        i = int(np.argmax(np.diag(r)))
        j, m = (i + 1) % 3, (i + 2) % 3
        k = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[m, m])
        q = [0.0, 0.0, 0.0, (r[m, j] - r[j, m]) / k]
        q[i] = k / 4.0
        q[j] = (r[j, i] + r[i, j]) / k
        q[m] = (r[m, i] + r[i, m]) / k
    return [float(x) for x in q]
