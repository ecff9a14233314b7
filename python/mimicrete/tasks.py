"""The task table: one place for the four tasks' names, ids and sizes.

The sizes come from the simulator itself (``tile-sim`` through ``_native.sim_constants()``); the
episode length, the effector kind, the success's name, the gesture classes and the task's sentence
from each task's built-in spec file (``crates/tile-sim/tasks/*.toml`` through
``_native.task_spec``, :meth:`TaskSpec.builtin_spec`);
the names are the user-facing ones (``suction``, ``grip``, ``screw``, ``row``), the simulator's
(``TileSuction``, ``BlockGrip``, ``Screw``, ``TileRow``) and the gymnasium ids
(``mimicrete/TileSuction-v0``). Everything else in the package looks tasks up here. A
researcher's own spec file runs one of these tasks' logic (:func:`load_task_file`).

The row (``TileRow``, issue 26 §2) runs everywhere the other tasks do (the simulator, its
gymnasium envs, the scripted demonstrator, the live page, the demos and their export) but demogen,
which refuses it with a :class:`NotBuiltError` (:func:`not_built`), which the CLI prints as one
line, exit 2.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

from mimicrete import _native
from mimicrete._native import MimicreteError

_CONST: dict[str, Any] = _native.sim_constants()
#: The simulator's shared constants, read here once for the whole package.
FRAME_STACK: int = int(_CONST["FRAME_STACK"])
MAX_EPISODE_STEPS: int = int(_CONST["MAX_EPISODE_STEPS"])
CONTROL_DT: float = float(_CONST["CONTROL_DT"])  # s per control step
MAX_JOINT_STEP: float = float(_CONST["MAX_JOINT_STEP"])  # rad per step per joint


@dataclass(frozen=True)
class TaskSpec:
    """One task: its names and the simulator's sizes for it."""

    name: str  # suction | grip | screw | row: the CLI's and the hand logs' name
    sim: str  # tile-sim's name
    gesture_model: str  # the spec's about.gestures: its classifier (gestures.TASK_CLASSES)
    success: str  # the spec's about.success ("installed", "placed", "screwed")
    obs_frame_dim: int
    obs_dim: int
    act_dim: int
    max_steps: int  # episode length in control steps (the spec's episode.max_steps)
    effector: str  # the spec's effector kind: suction | gripper
    instruction: str  # the spec's about.instruction: the task as one sentence

    @property
    def env_id(self) -> str:
        return f"mimicrete/{self.sim}-v0"

    def builtin_spec(self) -> dict[str, Any]:
        """The task's built-in spec (``crates/tile-sim/tasks/<task>.toml``) as a dict (a new one
        each call)."""
        return _native.task_spec(self.sim)


def _task(name: str, sim: str) -> TaskSpec:
    d = _CONST["tasks"][sim]
    spec = _native.task_spec(sim)
    return TaskSpec(
        name,
        sim,
        str(spec["about"]["gestures"]),
        str(spec["about"]["success"]),
        int(d["obs_frame_dim"]),
        int(d["obs_dim"]),
        int(d["act_dim"]),
        int(spec["episode"]["max_steps"]),
        str(spec["effector"]["kind"]),
        str(spec["about"]["instruction"]),
    )


TABLE: dict[str, TaskSpec] = {
    t.name: t
    for t in (
        _task("suction", "TileSuction"),
        _task("grip", "BlockGrip"),
        _task("screw", "Screw"),
        _task("row", "TileRow"),
        _task("place", "TilePlace"),
    )
}
TASKS: tuple[str, ...] = tuple(TABLE)
SIM_TASKS: tuple[str, ...] = tuple(t.sim for t in TABLE.values())
ENV_IDS: tuple[str, ...] = tuple(t.env_id for t in TABLE.values())

_ALIASES: dict[str, str] = {
    **{t.name: t.name for t in TABLE.values()},
    **{t.sim.lower(): t.name for t in TABLE.values()},
    "tilesuctionv0": "suction",
    "blockgripv0": "grip",
    "screwv0": "screw",
    "tilerowv0": "row",
    "tileplacev0": "place",
    "gripping": "grip",
    "screwing": "screw",
}


def get(name: str) -> TaskSpec:
    """The task named by any accepted spelling: ``suction``, ``TileSuction``,
    ``TileSuction-v0``, ``mimicrete/TileSuction-v0`` (case, ``-`` and ``_`` ignored)."""
    key = str(name).split("/")[-1].lower().replace("-", "").replace("_", "")
    if key not in _ALIASES:
        raise ValueError(
            f"unknown task {name!r}; known: {', '.join(TASKS)} (or {', '.join(ENV_IDS)})"
        )
    return TABLE[_ALIASES[key]]


class NotBuiltError(MimicreteError, ValueError):
    """A part of the package that is not built for a task yet (demogen for the row): the message
    is one line naming the part, the task and the tasks the part does handle (:func:`not_built`).
    The CLI prints it as one line and exits 2."""


def not_built(part: str, task: str, handled: tuple[str, ...] | list[str]) -> NotBuiltError:
    """The error saying ``part`` (e.g. ``"the scripted demonstrator"``) is not built for
    ``task`` (any spelling :func:`get` takes) yet; ``handled``: the tasks it is built for."""
    t = get(task)
    names = ", ".join(get(h).name for h in handled)
    return NotBuiltError(
        f"{part} is not built for the {t.name} task ({t.sim}) yet; it handles {names}"
    )


def load_task_file(path: str | os.PathLike[str]) -> tuple[TaskSpec, dict[str, Any]]:
    """A researcher's task spec file, read, checked and built once → the task whose logic it runs
    (tile-sim picks it from the effector: its names, gesture model and sizes) and the spec as a
    dict. Raises as ``_native.SimEnv.from_spec_file``: ``SimInputError`` for a bad spec (see
    :func:`task_file_error`), ``OSError`` for an unreadable file."""
    env = _native.SimEnv.from_spec_file(os.fspath(path), 0)
    return get(env.task), env.spec()


def task_file_meta(path: str | os.PathLike[str], spec: dict[str, Any]) -> dict[str, str]:
    """A demo's metadata naming the task spec file its episode ran in (``task_file``) and the
    spec as it was read (``task_spec``, JSON): what convert, the live server and demogen write,
    and what training and export check."""
    import json

    return {"task_file": os.fspath(path), "task_spec": json.dumps(spec, sort_keys=True)}


def task_file_error(path: str | os.PathLike[str], error: BaseException) -> str:
    """One line saying why the spec file ``path`` was refused: ``FILE: FIELD = VALUE: why`` for a
    bad value, ``FILE: line L, column C (the line's text): why`` for a TOML or structure error
    (an unknown field, a wrong type), ``FILE: why`` for a file that cannot be read."""
    path = os.fspath(path)
    field = getattr(error, "field", None)
    if field is not None:
        return f"{path}: {field} = {getattr(error, 'value', None)}: {getattr(error, 'reason', '')}"
    if isinstance(error, OSError):
        return f"{path}: {error.strerror or error}"
    line = getattr(error, "line", None)
    reason = " ".join(str(getattr(error, "reason", None) or error).split())
    if line is None:
        return f"{path}: {reason}"
    text = getattr(error, "text", "")
    shown = f" ({text})" if text else ""
    return f"{path}: line {line}, column {getattr(error, 'column', None)}{shown}: {reason}"
