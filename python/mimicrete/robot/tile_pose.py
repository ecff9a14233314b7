"""Where the tile is, for the observation: ``fixed:X,Y,YAW`` (m, m, rad; the tile lies on the
table there), ``file:PATH`` (a JSON object a line, ``{"x": .., "y": .., "yaw": ..}``, appended by
whatever tracks the tile; the newest complete line counts; the file must hold one line when the
run starts; a line that is not such an object stops the run naming the file, the line and why)
or ``aruco:CAMERA`` (a marker on the tile seen by a camera: :mod:`.aruco`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from mimicrete._native import MimicreteError


class TilePoseError(MimicreteError, ValueError):
    """A tile-pose source that cannot be used (names the source, the line and why)."""


class FixedTilePose:
    def __init__(self, x: float, y: float, yaw: float) -> None:
        self._pose = (float(x), float(y), float(yaw))
        self.label = "fixed"
        self.version = 0

    def pose(self) -> tuple[float, float, float]:
        return self._pose

    def close(self) -> None:
        pass


class FileTilePose:
    """The newest complete line of a JSON-lines file; ``version`` counts the updates read."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.label = f"file:{self.path}"
        self.version = 0
        self._line = 0
        self._buf = ""
        try:
            self._f = open(self.path, encoding="utf-8")  # noqa: SIM115 (kept open, tailed)
        except OSError as e:
            raise TilePoseError(f"--tile-pose file:{self.path}: {e.strerror or e}") from None
        self._pose: tuple[float, float, float] | None = None
        self._read()
        if self._pose is None:
            self._f.close()
            raise TilePoseError(
                f"--tile-pose file:{self.path}: no pose line yet (JSON lines of "
                '{"x": .., "y": .., "yaw": ..})'
            )

    def _read(self) -> None:
        self._buf += self._f.read()
        *lines, self._buf = self._buf.split("\n")
        for text in lines:
            self._line += 1
            if not text.strip():
                continue
            self._pose = parse_line(text, f"{self.path}:{self._line}")
            self.version += 1

    def pose(self) -> tuple[float, float, float]:
        self._read()
        assert self._pose is not None
        return self._pose

    def close(self) -> None:
        self._f.close()


def parse_line(text: str, where: str) -> tuple[float, float, float]:
    try:
        obj = json.loads(text)
    except ValueError as e:
        raise TilePoseError(f"{where}: not JSON ({e})") from None
    if not isinstance(obj, dict):
        raise TilePoseError(f"{where}: expected an object with x, y, yaw")
    out = []
    for k in ("x", "y", "yaw"):
        v = obj.get(k)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise TilePoseError(f"{where}: field {k!r} must be a finite number, got {v!r}")
        out.append(float(v))
    return out[0], out[1], out[2]
