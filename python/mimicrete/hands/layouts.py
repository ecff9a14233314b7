"""Hand joint layouts: the joint order of each tracking source and the maps between them.

OpenXR (``XrHandJointEXT``, 26: 0 palm, 1 wrist, 2-5 thumb metacarpal/proximal/distal/tip, then
index, middle, ring, little with metacarpal, proximal, intermediate, distal, tip), WebXR (25: OpenXR
without the palm), Meta OVR legacy (24) and MediaPipe (21). The table is ur3-kin's ``HandLayout``
(``mimicrete._native.kin_hand_layouts()``: each layout's joint names and each joint's OpenXR
joint); everything here is read or derived from it, so no index is stated twice."""

from __future__ import annotations

import numpy as np

from mimicrete import _native

# ----------------------------------------------------------------------------------------------
# Layouts (ur3-kin's table)
# ----------------------------------------------------------------------------------------------

_TABLE: dict[str, dict] = _native.kin_hand_layouts()

LAYOUT_JOINTS: dict[str, int] = {name: len(d["joints"]) for name, d in _TABLE.items()}
"""Joint count of each hand-log layout."""

JOINT_NAMES: dict[str, tuple[str, ...]] = {name: tuple(d["joints"]) for name, d in _TABLE.items()}
"""Each layout's joint names in its order, as its runtime names them (OpenXR: the names below;
WebXR: ``XRHandJoint``; Meta OVR: ``BoneId`` without ``Hand_``; MediaPipe: ``HandLandmark``)."""

OPENXR_NAMES: tuple[str, ...] = JOINT_NAMES["openxr"]
"""The OpenXR joints in OpenXR order (``palm``, ``wrist``, ``thumb_metacarpal``, …,
``little_tip``): the names :func:`joint_index` takes."""

WEBXR_JOINT_NAMES: tuple[str, ...] = JOINT_NAMES["webxr"]
"""WebXR's ``XRHandJoint`` joint names in its order (``layout: webxr`` and the wire format)."""

FROM_OPENXR: dict[str, tuple[int | None, ...]] = {
    name: tuple(d["openxr"]) for name, d in _TABLE.items()
}
"""The OpenXR index of each joint of each layout (None: a joint OpenXR has not)."""

#: OpenXR index of each MediaPipe landmark (WRIST, THUMB_CMC/MCP/IP/TIP, then per finger
#: MCP, PIP, DIP, TIP). MCP is the OpenXR *proximal* joint; the thumb CMC is its *metacarpal*.
MEDIAPIPE_FROM_OPENXR: tuple[int, ...] = tuple(int(i) for i in FROM_OPENXR["mediapipe"])
#: OpenXR index of each WebXR joint (OpenXR without the palm).
WEBXR_FROM_OPENXR: tuple[int, ...] = tuple(int(i) for i in FROM_OPENXR["webxr"])
#: OpenXR index of each OVR legacy bone that has an OpenXR counterpart, ``-1`` for the two OVR
#: bones OpenXR lacks (ForearmStub, Thumb0/trapezium), which :func:`to_layout` synthesises.
OVR_FROM_OPENXR: tuple[int, ...] = tuple(-1 if i is None else i for i in FROM_OPENXR["meta_ovr"])

#: The 21 landmarks every layout carries, in MediaPipe order, as indices into each layout.
CANONICAL21: dict[str, tuple[int, ...]] = {
    name: tuple(m.index(i) for i in MEDIAPIPE_FROM_OPENXR) for name, m in FROM_OPENXR.items()
}

#: (wrist, index proximal, middle proximal) indices per layout (reference note §4): the joints
#: the hand frame (ur3-kin's ``hand_to_target``) reads.
FRAME_JOINTS: dict[str, tuple[int, int, int]] = {
    name: (d["wrist"], d["index_proximal"], d["middle_proximal"]) for name, d in _TABLE.items()
}


def joint_index(layout: str, joint: str) -> int:
    """Where the OpenXR joint named ``joint`` (one of :data:`OPENXR_NAMES`) sits in ``layout``.

    Raises:
        ValueError: for an unknown layout or joint name, or a joint the layout lacks.
    """
    layout = check_layout(layout)
    if joint not in OPENXR_NAMES:
        raise ValueError(f"unknown OpenXR joint {joint!r}; known: {', '.join(OPENXR_NAMES)}")
    m = FROM_OPENXR[layout]
    ox = OPENXR_NAMES.index(joint)
    if ox not in m:
        raise ValueError(f"layout {layout} has no {joint} joint")
    return m.index(ox)


def check_layout(layout: str) -> str:
    """Normalise a layout name (``-``/``_`` and case are ignored).

    Raises:
        ValueError: for an unknown layout, naming the known ones.
    """
    name = layout.lower().replace("-", "_")
    if name not in LAYOUT_JOINTS:
        raise ValueError(f"unknown hand layout {layout!r}; known: {sorted(LAYOUT_JOINTS)}")
    return name


_OX_WRIST, _OX_MIDDLE_PROXIMAL, _OX_THUMB_METACARPAL = (
    OPENXR_NAMES.index(n) for n in ("wrist", "middle_proximal", "thumb_metacarpal")
)
_OVR_FOREARM_STUB, _OVR_TRAPEZIUM = (
    JOINT_NAMES["meta_ovr"].index(n) for n in ("ForearmStub", "Thumb0")
)


def to_layout(openxr: np.ndarray, layout: str) -> np.ndarray:
    """Map OpenXR joints ``(..., 26, 3)`` to another layout ``(..., N, 3)``.

    The two OVR legacy bones without an OpenXR joint are placed where the OVR skeleton puts
    them: the forearm stub 5 cm (scaled by hand size) behind the wrist along the hand's axis, and
    the trapezium (Thumb0) halfway between the wrist and the thumb's carpometacarpal joint.
    """
    layout = check_layout(layout)
    j = np.asarray(openxr, dtype=np.float64)
    n = LAYOUT_JOINTS["openxr"]
    if j.shape[-2:] != (n, 3):
        raise ValueError(f"expected OpenXR joints of shape (..., {n}, 3), got {j.shape}")
    if layout == "openxr":
        return j.copy()
    if layout == "webxr":
        return j[..., WEBXR_FROM_OPENXR, :].copy()
    if layout == "mediapipe":
        return j[..., MEDIAPIPE_FROM_OPENXR, :].copy()
    idx = np.array([max(i, 0) for i in OVR_FROM_OPENXR])
    out = j[..., idx, :].copy()
    wrist, mid = j[..., _OX_WRIST, :], j[..., _OX_MIDDLE_PROXIMAL, :]
    out[..., _OVR_FOREARM_STUB, :] = wrist - 0.55 * (mid - wrist)
    out[..., _OVR_TRAPEZIUM, :] = 0.5 * (wrist + j[..., _OX_THUMB_METACARPAL, :])
    return out


def canonical21(joints: np.ndarray, layout: str) -> np.ndarray:
    """The 21 MediaPipe-ordered landmarks ``(..., 21, D)`` of joints given in ``layout``."""
    layout = check_layout(layout)
    j = np.asarray(joints, dtype=np.float64)
    if j.shape[-2] != LAYOUT_JOINTS[layout]:
        raise ValueError(
            f"layout {layout} has {LAYOUT_JOINTS[layout]} joints, got array of shape {j.shape}"
        )
    return j[..., CANONICAL21[layout], :]
