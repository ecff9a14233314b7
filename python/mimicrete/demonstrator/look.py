"""What the person sees during an episode: the one look the scripted person takes after the start.

A tile set down to a tiler's few millimetres and 2° is set down by eye: before the last
centimetre the person looks at the held tile over its pad and, while setting it down, moves the
hand by the tile's offset from its target and turns it by the tile's turn from square to the pad
(TilePlace, :data:`BY_EYE`). Everything before that look is planned open loop from the start's
scene (:mod:`.scene`), and so is everything after it but that correction.

The look runs the hand frames up to it through the teleoperation session exactly as ``mimicrete
convert`` will (:class:`mimicrete.teleop.session.Session`: the task's shipped gesture model,
absolute mapping, the frames as the hand log stores them), so what the person sees is where the
converted demo's tile is at that frame. Why it is needed: in tile-sim a tile sealed 1 mm off
the cups' centre drifts away from it, to about 6 mm off after ten seconds held still, and
without the look 30 of 40 scripted placements (``synth-hands --task place --seed 0``, converted)
were placed, the other 10 let go 5-12 mm off the target's centre; with it 179 of 180 (seeds
0-2, 60 each).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: The tasks whose person sets the object down by eye, and the phase it is set down in
#: (:meth:`.motion.Motion.set_down`; the look is taken as it starts).
BY_EYE: dict[str, str] = {"place": "set_down"}
#: How well the person judges the object's offset from its target by eye: the standard deviation
#: of the error on each horizontal axis (mm) and of its turn (degrees), the edges of a tile
#: against a pad's seen from a step away.
EYE_MM = 1.0
EYE_DEG = 0.3


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
    object to the target (rad about Base Z, :func:`.scene.square_turn`) after the hand frames
    ``t``, ``tracked``, ``joints`` (in ``layout``, stored as a hand log rounds them) ran through
    the teleoperation session of episode ``seed`` of ``task`` (in ``task_file``'s spec if
    given)."""
    from mimicrete.teleop.session import Session

    from .scene import square_turn, yaw_of

    session = Session(task, layout, handedness, calib, int(seed), task_file=task_file)
    for k in range(len(t)):
        session.push(float(t[k]), bool(tracked[k]), np.round(joints[k], 5))
        if session.done:
            break
    snap = session.snapshot()
    obj, target = snap["object"], snap["target"]
    dx, dy = (np.asarray(target["t"]) - np.asarray(obj["t"]))[:2]
    return np.array([dx, dy, square_turn(yaw_of(obj["q"]), yaw_of(target["q"]))])
