"""Hand logs (JSON Lines, ``mimicrete.handlog`` version 1): parse into numpy arrays, write.

Line 1 is the header (format, version, layout, space, handedness, units, and optionally task,
episode_seed, source, extra); every further line is a frame ``{"t", "tracked", "joints",
"orientations"?}``. See ``docs/formats.md``. Parsing and validation are done in Rust
(``demo-log``); errors raise ``mimicrete.LogFormatError`` with ``file:line: reason``.

    >>> log = mc.hands.parse("hand.jsonl")             # strict: first bad line raises
    >>> log.joints.shape                                  # (T, J, 3) metres
    >>> log = mc.hands.parse("hand.jsonl", mode="lenient"); log.report["skipped"]
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from mimicrete import _native

from .layouts import LAYOUT_JOINTS

__all__ = ["LAYOUT_JOINTS", "HandLogData", "header", "parse", "parse_text", "write"]


def header(layout: str, space: str, handedness: str, **more: Any) -> dict[str, Any]:
    """A hand log's header line (format ``mimicrete.handlog`` version 1, units m): the required
    fields, then ``more`` (task, episode_seed, source, extra) in the order given."""
    return {
        "format": "mimicrete.handlog",
        "version": 1,
        "layout": layout,
        "space": space,
        "handedness": handedness,
        "units": "m",
        **more,
    }


@dataclass
class HandLogData:
    """A parsed hand log: ``header`` (dict), ``t`` (T,) s, ``tracked`` (T,) bool, ``joints``
    (T, J, 3) m, ``orientations`` (T, J, 4) xyzw or None, ``report`` (frame_lines, kept,
    untracked_skipped, invalid_skipped, skipped [(line, reason)])."""

    header: dict[str, Any]
    t: np.ndarray
    tracked: np.ndarray
    joints: np.ndarray
    orientations: np.ndarray | None
    report: dict[str, Any]

    def __len__(self) -> int:
        return int(self.t.shape[0])


def _wrap(d: dict[str, Any]) -> HandLogData:
    return HandLogData(
        header=dict(d["header"]),
        t=d["t"],
        tracked=d["tracked"],
        joints=d["joints"],
        orientations=d["orientations"],
        report=dict(d["report"]),
    )


def parse(path: str | os.PathLike[str], mode: str = "strict") -> HandLogData:
    """Parse a hand-log file. ``mode="lenient"`` skips bad and untracked frames (see ``report``)."""
    return _wrap(_native.demo_parse_handlog(os.fspath(path), mode))


def parse_text(text: str, name: str = "<string>", mode: str = "strict") -> HandLogData:
    """Parse hand-log text; ``name`` stands for the file name in error messages."""
    return _wrap(_native.demo_parse_handlog_str(text, name, mode))


def write(
    path: str | os.PathLike[str],
    header: dict[str, Any],
    t: np.ndarray,
    tracked: np.ndarray,
    joints: np.ndarray,
    orientations: np.ndarray | None = None,
) -> None:
    """Write a hand log atomically. ``header`` needs layout, space, handedness (task,
    episode_seed, source, extra optional). Invalid content (wrong joint count, NaN, time going
    backwards) raises ``LogFormatError`` and writes nothing."""
    _native.demo_write_handlog(
        os.fspath(path),
        header,
        np.ascontiguousarray(t, dtype=np.float64),
        np.ascontiguousarray(tracked, dtype=np.bool_),
        np.ascontiguousarray(joints, dtype=np.float64),
        None if orientations is None else np.ascontiguousarray(orientations, dtype=np.float64),
    )
