"""The hand: joint layouts (OpenXR 26, WebXR 25, Meta OVR 24, MediaPipe 21), the parametric hand
model the scripted demonstrator and the built-in gesture data are made with, and hand-log I/O
(the JSON Lines format of docs/formats.md, parsed and written by the Rust crate demo-log)."""

from __future__ import annotations

from .layouts import CANONICAL21, FRAME_JOINTS, LAYOUT_JOINTS, canonical21, check_layout, to_layout
from .log import HandLogData, parse, parse_text, write

__all__ = [
    "CANONICAL21",
    "FRAME_JOINTS",
    "LAYOUT_JOINTS",
    "HandLogData",
    "canonical21",
    "check_layout",
    "parse",
    "parse_text",
    "to_layout",
    "write",
]
