"""What the live page draws, besides the scene itself: the poses of the scene's frames, the end
effector's state, and where the scene sits in the user's tracking space.

The scene is the one the demos' ``/scene`` carries, made in one place (demo-log's ``scene.rs``,
through the bindings): ``SimEnv.scene_entities()`` gives its Foxglove ``SceneEntity`` JSON (the
robot frame-locked to the URDF links, the table, pad, target, end effector in ``tool0`` and the
object in ``tile``), and :func:`frame_poses` poses those frames from one simulator snapshot.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mimicrete import _native, kin
from mimicrete.kin import Calibration


def frame_poses(snap: dict[str, Any], model: str = "ur3") -> dict[str, list[float]]:
    """``{frame_id: [x, y, z, qx, qy, qz, qw]}`` in Base of every frame the scene's entities are
    locked to (the URDF links ``shoulder_link`` … ``tool0`` of the arm ``model`` at the
    snapshot's joints, ``tile`` at its object, a row's ``tile_0`` … at its tiles; ``base`` is the
    identity and not listed), from a snapshot the caller already has: ``_native.scene_frames``,
    the frames ``SimEnv.scene_frames()`` and the demos' ``/tf`` give. ``model``: the spec's
    ``robot.model`` (the built-in tasks' arm is the UR3)."""
    o = snap["object"]
    row = [[*r["object"]["t"], *r["object"]["q"]] for r in snap.get("row") or []]
    return _native.scene_frames(snap["q"], [*o["t"], *o["q"]], model=model, row=row)


#: What the person should do when the robot does not follow, by the reason (the HUD's line).
HINTS: dict[str | None, str] = {
    "no hand yet": "show your right hand to the headset: the robot engages on it",
    "hand not tracked": "bring your right hand back into the headset's view",
    "not engaged": "the clutch is released: move your hand where it is comfortable, then Engage",
    "target unreachable": "out of the arm's reach: move your hand back toward the robot "
    "(the ghost marks where the tool is asked to go)",
    "not recording": "following (not recorded): pinch your left hand 1 s or press Start to record",
}


def follow_why(session: Any, last_step: Any, recording: bool) -> str | None:
    """Why the arm does not follow the hand now (None: it does), from the session and its
    newest control step (None before one)."""
    if session.target is None:
        return "no hand yet"
    if session.last_tracked is False:
        return "hand not tracked"
    if last_step is not None and last_step.why in ("target unreachable", "not engaged"):
        return str(last_step.why)
    return None if recording else "not recording"


def effector_state(task: str, snap: dict[str, Any]) -> dict[str, Any]:
    """The end effector's state for the HUD and the drawing (``task``: any task of the table; the
    row's is its suction head's)."""
    from mimicrete import tasks

    t = tasks.get(task)
    if t.effector == "suction":
        return {"kind": "suction", "on": bool(snap["suction_on"])}
    if t.name == "grip":
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


def task_calibration(
    task: str = "suction", task_file: str | None = None, base: Calibration | None = None
) -> Calibration:
    """``base`` (None: :func:`standing_calibration`) for the task spec file ``task_file`` (None:
    ``task``'s built-in spec): Base scaled about the robot's base by the spec's hand scale
    (``_native.hand_scale``: its ``robot.hand_scale``, else its arm's workspace scale, tile-sim's
    ``workspace_scale``; 1 for the UR3 tasks, which get ``base`` unchanged). The workspace centre
    and the head's height and distance scale with it, so a person standing as at the UR3, hands
    moving the UR3-size distances, reaches across the larger arm's scene, drawn ``1/scale`` the
    size. What ``mimicrete teleop``, the scripted live client and ``synth-hands`` map hands with."""
    base = standing_calibration() if base is None else base
    return base.scaled(_native.hand_scale(task, task_file))


def view_from_base(calibration: Calibration) -> list[float]:
    """The 4×4 (column-major) from Base into the tracking space: the inverse of the calibration's
    affine map, read off ur3-kin's ``points_to_base`` (so the axis change lives in one place)."""
    basis = np.vstack([np.zeros(3), np.eye(3)])
    p = kin.points_to_base(basis, calibration)
    m = np.eye(4)
    m[:3, :3] = (p[1:] - p[0]).T  # columns: images of the unit vectors
    m[:3, 3] = p[0]
    return np.linalg.inv(m).reshape(-1, order="F").tolist()
