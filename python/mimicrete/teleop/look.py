"""What the scripted person sees when it looks at the robot: the hand frames so far run through the
teleoperation session exactly as ``mimicrete convert`` will run them (the task's shipped gesture
model, absolute mapping, the frames as a hand log stores them), so what the person sees is where
the converted demo's object is at that frame.

The demonstrator (:mod:`mimicrete.demonstrator.look`) takes this as an argument (``see``), so
that the hand's package does not import the teleoperation that reads its hands: the commands
(``mimicrete synth-hands``, ``train --make-demos``) hand it in.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from mimicrete.demonstrator.scene import square_turn, yaw_of
from mimicrete.teleop.session import Session


def offset_seen(
    task: str,
    seed: int,
    t: np.ndarray,
    tracked: np.ndarray,
    joints: np.ndarray,
    layout: str,
    handedness: str,
    calib: Any,
    task_file: str | None = None,
) -> np.ndarray:
    """The target's centre minus the object's (Base x, y; m) and the least turn that squares the
    object to the target (rad about Base Z, :func:`mimicrete.demonstrator.scene.square_turn`)
    after the hand frames ``t``, ``tracked``, ``joints`` (in ``layout``, stored as a hand log
    rounds them) ran through the teleoperation session of episode ``seed`` of ``task`` (in
    ``task_file``'s spec if given)."""
    session = Session(task, layout, handedness, calib, int(seed), task_file=task_file)
    for k in range(len(t)):
        session.push(float(t[k]), bool(tracked[k]), np.round(joints[k], 5))
        if session.done:
            break
    snap = session.snapshot()
    obj, target = snap["object"], snap["target"]
    dx, dy = (np.asarray(target["t"]) - np.asarray(obj["t"]))[:2]
    return np.array([dx, dy, square_turn(yaw_of(obj["q"]), yaw_of(target["q"]))])
