"""Hand joint layouts: the joint order of each tracking source and the maps between them.

OpenXR (``XrHandJointEXT``, 26: 0 palm, 1 wrist, 2-5 thumb metacarpal/proximal/distal/tip, then
index, middle, ring, little with metacarpal, proximal, intermediate, distal, tip), WebXR (25: OpenXR
without the palm), Meta OVR legacy (24) and MediaPipe (21). ur3-kin's ``HandLayout`` is the same
table on the Rust side (the hand-log parser checks joint counts with it)."""

from __future__ import annotations

import numpy as np

# ----------------------------------------------------------------------------------------------
# Layouts
# ----------------------------------------------------------------------------------------------

LAYOUT_JOINTS: dict[str, int] = {"openxr": 26, "webxr": 25, "meta_ovr": 24, "mediapipe": 21}
"""Joint count of each hand-log layout."""

OPENXR_NAMES: tuple[str, ...] = (
    "palm",
    "wrist",
    "thumb_metacarpal",
    "thumb_proximal",
    "thumb_distal",
    "thumb_tip",
    "index_metacarpal",
    "index_proximal",
    "index_intermediate",
    "index_distal",
    "index_tip",
    "middle_metacarpal",
    "middle_proximal",
    "middle_intermediate",
    "middle_distal",
    "middle_tip",
    "ring_metacarpal",
    "ring_proximal",
    "ring_intermediate",
    "ring_distal",
    "ring_tip",
    "little_metacarpal",
    "little_proximal",
    "little_intermediate",
    "little_distal",
    "little_tip",
)

#: OpenXR index of each MediaPipe landmark (WRIST, THUMB_CMC/MCP/IP/TIP, then per finger
#: MCP, PIP, DIP, TIP). MCP is the OpenXR *proximal* joint; the thumb CMC is its *metacarpal*.
MEDIAPIPE_FROM_OPENXR: tuple[int, ...] = (
    1,
    2,
    3,
    4,
    5,
    7,
    8,
    9,
    10,
    12,
    13,
    14,
    15,
    17,
    18,
    19,
    20,
    22,
    23,
    24,
    25,
)
#: OpenXR index of each WebXR joint (OpenXR without the palm).
WEBXR_JOINT_NAMES: tuple[str, ...] = (
    "wrist",
    "thumb-metacarpal",
    "thumb-phalanx-proximal",
    "thumb-phalanx-distal",
    "thumb-tip",
    *(
        f"{finger}-{part}"
        for finger in ("index-finger", "middle-finger", "ring-finger", "pinky-finger")
        for part in (
            "metacarpal",
            "phalanx-proximal",
            "phalanx-intermediate",
            "phalanx-distal",
            "tip",
        )
    ),
)
"""WebXR's ``XRHand`` joint names in its order (``layout: webxr`` and the wire format)."""

WEBXR_FROM_OPENXR: tuple[int, ...] = tuple(range(1, 26))
#: OpenXR index of each OVR legacy bone that has an OpenXR counterpart, ``-1`` for the two OVR
#: bones OpenXR lacks (1 ForearmStub, 2 Thumb0/trapezium), which :func:`to_layout` synthesises.
#: OVR order: 0 WristRoot, 1 ForearmStub, 2-5 Thumb0-3, 6-8 Index1-3, 9-11 Middle1-3,
#: 12-14 Ring1-3, 15-18 Pinky0-3, 19-23 Thumb/Index/Middle/Ring/Pinky tips.
OVR_FROM_OPENXR: tuple[int, ...] = (
    1,
    -1,
    -1,
    2,
    3,
    4,
    7,
    8,
    9,
    12,
    13,
    14,
    17,
    18,
    19,
    21,
    22,
    23,
    24,
    5,
    10,
    15,
    20,
    25,
)

#: The 21 landmarks every layout carries, in MediaPipe order, as indices into each layout.
CANONICAL21: dict[str, tuple[int, ...]] = {
    "openxr": MEDIAPIPE_FROM_OPENXR,
    "webxr": tuple(i - 1 for i in MEDIAPIPE_FROM_OPENXR),
    "meta_ovr": (0, 3, 4, 5, 19, 6, 7, 8, 20, 9, 10, 11, 21, 12, 13, 14, 22, 16, 17, 18, 23),
    "mediapipe": tuple(range(21)),
}

#: (wrist, index proximal, middle proximal) indices per layout (reference note §4).
FRAME_JOINTS: dict[str, tuple[int, int, int]] = {
    "openxr": (1, 7, 12),
    "webxr": (0, 6, 11),
    "meta_ovr": (0, 6, 9),
    "mediapipe": (0, 5, 9),
}


def check_layout(layout: str) -> str:
    """Normalise a layout name (``-``/``_`` and case are ignored).

    Raises:
        ValueError: for an unknown layout, naming the known ones.
    """
    name = layout.lower().replace("-", "_")
    if name not in LAYOUT_JOINTS:
        raise ValueError(f"unknown hand layout {layout!r}; known: {sorted(LAYOUT_JOINTS)}")
    return name


def to_layout(openxr: np.ndarray, layout: str) -> np.ndarray:
    """Map OpenXR joints ``(..., 26, 3)`` to another layout ``(..., N, 3)``.

    The two OVR legacy bones without an OpenXR joint are placed where the OVR skeleton puts
    them: the forearm stub 5 cm (scaled by hand size) behind the wrist along the hand's axis, and
    the trapezium (Thumb0) halfway between the wrist and the thumb's carpometacarpal joint.
    """
    layout = check_layout(layout)
    j = np.asarray(openxr, dtype=np.float64)
    if j.shape[-2:] != (26, 3):
        raise ValueError(f"expected OpenXR joints of shape (..., 26, 3), got {j.shape}")
    if layout == "openxr":
        return j.copy()
    if layout == "webxr":
        return j[..., WEBXR_FROM_OPENXR, :].copy()
    if layout == "mediapipe":
        return j[..., MEDIAPIPE_FROM_OPENXR, :].copy()
    idx = np.array([max(i, 0) for i in OVR_FROM_OPENXR])
    out = j[..., idx, :].copy()
    wrist, mid = j[..., 1, :], j[..., 12, :]
    out[..., 1, :] = wrist - 0.55 * (mid - wrist)
    out[..., 2, :] = 0.5 * (wrist + j[..., 2, :])
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
