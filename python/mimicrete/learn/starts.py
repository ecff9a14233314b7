"""Which starts an evaluation (or a training) runs its episodes from.

Three are named, tile-sim's variations (its ``starts`` module gives their ranges):

* ``training``: the paper's starts (tile x uniform in [0, 0.15] m at y = 0.32 m, the target fixed),
  where demos are recorded and policies are trained;
* ``robust``: the tile's x range widened by half on each side and the target moved by up to 2 cm;
* ``wide``: the object over 0.25 m of x and 0.10 m of y, turned by up to ±30°, the target and its
  pad moved by up to ±4 cm in x and y (the bolt plate spread likewise for Screw).

A **starts file** lists explicit starts, one JSON object a line, as ``reset(options=…)`` takes
them: ``{"object_pose": [x, y, yaw], "target_offset": [dx, dy]}`` (m, rad, Base frame;
``target_offset`` optional, the pad moves with the target). Blank lines and lines starting with
``#`` are skipped. A bad line is refused as ``file:line: reason``, a start the simulator refuses
(off the table, on the pad, out of reach) as ``file:line: <field> …``.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mimicrete import _native
from mimicrete._native import MimicreteError

NAMED = ("training", "robust", "wide")
MAX_FILE_BYTES = 16 * 1024 * 1024


class StartsFileError(MimicreteError, ValueError):
    """A starts file that cannot be read: ``file:line: reason``."""


@dataclass(frozen=True)
class StartList:
    """Explicit starts read from a file: what ``reset(options=…)`` takes, one per episode."""

    path: Path
    sha256: str
    starts: tuple[dict[str, list[float]], ...]

    @property
    def label(self) -> str:
        """The name reports give these starts: ``file:<path>``."""
        return f"file:{self.path}"


def _line_start(obj: Any, where: str) -> dict[str, list[float]]:
    if not isinstance(obj, dict):
        raise StartsFileError(f"{where}: expected a JSON object, got {type(obj).__name__}")
    unknown = sorted(set(obj) - {"object_pose", "target_offset"})
    if unknown:
        raise StartsFileError(
            f"{where}: unknown field {unknown[0]!r} (expected object_pose, target_offset)"
        )
    if "object_pose" not in obj:
        raise StartsFileError(f"{where}: missing object_pose [x, y, yaw]")
    out: dict[str, list[float]] = {}
    for key, n in (("object_pose", 3), ("target_offset", 2)):
        if key not in obj:
            continue
        v = obj[key]
        ok = isinstance(v, list) and len(v) == n
        ok = ok and all(isinstance(e, (int, float)) and not isinstance(e, bool) for e in v)
        if not ok:
            raise StartsFileError(f"{where}: {key} must be a list of {n} numbers, got {v!r}")
        out[key] = [float(e) for e in v]
    return out


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    keys = [k for k, _ in pairs]
    for k in keys:
        if keys.count(k) > 1:
            raise ValueError(f"duplicate key {k!r}")
    return dict(pairs)


def read_starts_file(path: str | Path, task: str, task_file: str | None = None) -> StartList:
    """The explicit starts in ``path`` for ``task`` (in the task spec file ``task_file`` if
    given), each checked by the simulator; raises :class:`StartsFileError` naming the file and
    line."""
    p = Path(path)
    if not p.is_file():
        raise StartsFileError(f"{p}: no such starts file (or not a regular file)")
    data = p.read_bytes()[: MAX_FILE_BYTES + 1]
    if len(data) > MAX_FILE_BYTES:
        raise StartsFileError(f"{p}: larger than {MAX_FILE_BYTES} bytes")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise StartsFileError(f"{p}:{line}: not UTF-8 text") from None
    if task_file is None:
        sim = _native.SimEnv(task, 0)
    else:
        sim = _native.SimEnv.from_spec_file(task_file, 0)
    starts: list[dict[str, list[float]]] = []
    for k, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        where = f"{p}:{k}"
        try:
            obj = json.loads(line, object_pairs_hook=_no_duplicates)
        except (json.JSONDecodeError, ValueError) as e:
            raise StartsFileError(f"{where}: not a JSON object ({str(e)[:120]})") from None
        st = _line_start(obj, where)
        try:
            sim.reset(0, **st)
        except ValueError as e:
            raise StartsFileError(f"{where}: {e}") from None
        starts.append(st)
    if not starts:
        raise StartsFileError(f"{p}: no starts in the file")
    return StartList(p, hashlib.sha256(data).hexdigest(), tuple(starts))


def resolve(starts: str | Path, env_id: str, task_file: str | None = None) -> str | StartList:
    """A named start set (``training``, ``robust``, ``wide``) or a starts file for the task of
    ``env_id`` (``Task-v0``: of the spec file ``task_file``)."""
    s = str(starts)
    if s in NAMED:
        return s
    if s.endswith(".jsonl") or Path(s).exists():
        from mimicrete.envs import task_of

        if task_file is not None:
            return read_starts_file(s, "", task_file)
        return read_starts_file(s, task_of(env_id))
    raise StartsFileError(f"starts: expected training, robust, wide or a FILE.jsonl, got {s!r}")


def label(starts: str | StartList) -> str:
    """How reports name the starts."""
    return starts if isinstance(starts, str) else starts.label
