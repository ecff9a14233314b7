"""The left hand's episode controls in the headset: a pinch (thumb tip to index tip under
:data:`PINCH_M`) held for :data:`PINCH_HOLD_S` fires once, a fist held for :data:`FIST_HOLD_S`
fires once per frame while it lasts. What they do (start / stop, discard, the gesture mode's
next step) is the caller's: :meth:`LeftHandControl.update` only says which one fired."""

from __future__ import annotations

import numpy as np

from mimicrete.hands.layouts import joint_index

from .protocol import WireFrame

PINCH_M = 0.02  # thumb tip to index tip, left hand
PINCH_HOLD_S = 1.0
#: the WebXR joints read (a frame's ``left`` is in WebXR order; indices from ur3-kin's layout table)
THUMB_TIP, INDEX_TIP = joint_index("webxr", "thumb_tip"), joint_index("webxr", "index_tip")
FINGERTIPS = tuple(joint_index("webxr", f"{f}_tip") for f in ("index", "middle", "ring", "little"))
WRIST, MIDDLE_PROXIMAL = joint_index("webxr", "wrist"), joint_index("webxr", "middle_proximal")
#: a left fist: the four fingertips' mean distance to the wrist under this share of the
#: wrist → middle-knuckle length (an open hand is about 1.9, a fist about 0.7)
FIST_RATIO = 0.85
FIST_HOLD_S = 1.5


def is_fist(f: WireFrame) -> bool:
    """The tracked left hand is a fist."""
    if not f.left_tracked:
        return False
    j = f.left
    size = float(np.linalg.norm(j[MIDDLE_PROXIMAL] - j[WRIST]))
    reach = float(np.mean(np.linalg.norm(j[list(FINGERTIPS)] - j[WRIST], axis=1)))
    return size > 1e-3 and reach < FIST_RATIO * size


def is_pinch(f: WireFrame) -> bool:
    """The tracked left hand pinches (thumb tip and index tip together)."""
    return f.left_tracked and bool(np.linalg.norm(f.left[THUMB_TIP] - f.left[INDEX_TIP]) < PINCH_M)


class LeftHandControl:
    """How long the left hand has pinched or made a fist, in the hand's own clock."""

    def __init__(self) -> None:
        self.pinch_since: float | None = None
        self.fist_since: float | None = None
        self.pinch_fired = False

    def update(self, f: WireFrame) -> str | None:
        """``"fist"`` while a fist has been held long enough, ``"pinch"`` on the frame a held
        pinch fires (once per pinch), else None."""
        if is_fist(f):
            if self.fist_since is None:
                self.fist_since = f.t
            self.pinch_since, self.pinch_fired = None, False
            return "fist" if f.t - self.fist_since >= FIST_HOLD_S else None
        self.fist_since = None
        if not is_pinch(f):
            self.pinch_since, self.pinch_fired = None, False
            return None
        if self.pinch_since is None:
            self.pinch_since = f.t
        if not self.pinch_fired and f.t - self.pinch_since >= PINCH_HOLD_S:
            self.pinch_fired = True
            return "pinch"
        return None
