"""The live teleoperation protocol, version 1 (docs/formats.md §3): hand frames in, JSON out.

A hand frame is one binary WebSocket message of :data:`FRAME_BYTES` bytes, little-endian:
magic ``MHF1``, ``u32 seq``, ``f64 t`` (the XR frame's time, seconds), ``f64 sent_ms`` (the
client's clock, echoed back for the round trip), ``u32 flags`` (bit 0 right hand tracked, bit 1
left), ``u32`` reserved, then 25 × (x, y, z) ``f32`` for the right hand and the same for the
left, metres, WebXR joint order, in the XR ``local`` space. Everything else is JSON text.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from mimicrete._native import MimicreteError
from mimicrete.hands.layouts import LAYOUT_JOINTS

VERSION = 1
MAGIC = b"MHF1"
JOINTS = LAYOUT_JOINTS["webxr"]  # WebXR hand joints (25)
HEADER = struct.Struct("<4sIddII")
FRAME_BYTES = HEADER.size + 2 * JOINTS * 3 * 4  # 632
RIGHT_TRACKED, LEFT_TRACKED = 1, 2


class FrameError(MimicreteError, ValueError):
    """A binary message that is not a valid hand frame; ``kind`` is the drop counter it feeds."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind


@dataclass
class WireFrame:
    """One decoded binary hand frame as the page sends it (both hands, WebXR layout); a hand
    log's frame is ``mimicrete.hands.log``'s, one hand in any layout."""

    seq: int
    t: float
    sent_ms: float
    right_tracked: bool
    left_tracked: bool
    right: np.ndarray  # (25, 3) float64
    left: np.ndarray  # (25, 3) float64


def parse_frame(data: bytes) -> WireFrame:
    """Decode one binary hand frame. Raises :class:`FrameError` (``malformed``: wrong size or
    magic; ``nan``: a non-finite time or a non-finite joint of a hand marked tracked)."""
    if len(data) != FRAME_BYTES:
        raise FrameError("malformed", f"hand frame of {len(data)} bytes, expected {FRAME_BYTES}")
    magic, seq, t, sent_ms, flags, _ = HEADER.unpack_from(data)
    if magic != MAGIC:
        raise FrameError("malformed", f"bad magic {magic!r}, expected {MAGIC!r}")
    hands = np.frombuffer(data, dtype="<f4", offset=HEADER.size).astype(np.float64)
    right, left = hands[: JOINTS * 3].reshape(JOINTS, 3), hands[JOINTS * 3 :].reshape(JOINTS, 3)
    rt, lt = bool(flags & RIGHT_TRACKED), bool(flags & LEFT_TRACKED)
    if not np.isfinite(t) or not np.isfinite(sent_ms):
        raise FrameError("nan", "non-finite frame time")
    if (rt and not np.all(np.isfinite(right))) or (lt and not np.all(np.isfinite(left))):
        raise FrameError("nan", "non-finite joint position in a tracked hand")
    return WireFrame(int(seq), float(t), float(sent_ms), rt, lt, right, left)


def pack_frame(
    seq: int,
    t: float,
    sent_ms: float,
    right: np.ndarray | None,
    left: np.ndarray | None = None,
) -> bytes:
    """Encode a hand frame (a hand that is None is sent untracked). The page's packer does the
    same in JavaScript; this one serves tests, benchmarks and other clients."""
    flags = (RIGHT_TRACKED if right is not None else 0) | (LEFT_TRACKED if left is not None else 0)
    zeros = np.zeros((JOINTS, 3))
    body = np.concatenate(
        [np.asarray(h if h is not None else zeros, dtype="<f4").reshape(-1) for h in (right, left)]
    )
    return HEADER.pack(MAGIC, seq & 0xFFFFFFFF, t, sent_ms, flags, 0) + body.tobytes()
