"""The task table: one place for the three tasks' names, ids and sizes.

The sizes come from the simulator itself (``tile-sim`` through ``_native.sim_constants()``); the
names are the user-facing ones (``suction``, ``grip``, ``screw``), the simulator's
(``TileSuction``, ``BlockGrip``, ``Screw``) and the gymnasium ids (``mimicrete/TileSuction-v0``).
Everything else in the package looks tasks up here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from mimicrete import _native

_CONST: dict[str, Any] = _native.sim_constants()
#: The simulator's shared constants, read here once for the whole package.
FRAME_STACK: int = int(_CONST["FRAME_STACK"])
MAX_EPISODE_STEPS: int = int(_CONST["MAX_EPISODE_STEPS"])
CONTROL_DT: float = float(_CONST["CONTROL_DT"])  # s per control step
MAX_JOINT_STEP: float = float(_CONST["MAX_JOINT_STEP"])  # rad per step per joint


@dataclass(frozen=True)
class TaskSpec:
    """One task: its names and the simulator's sizes for it."""

    name: str  # suction | grip | screw: the CLI's and the hand logs' name
    sim: str  # tile-sim's name
    gesture_model: str  # the gesture classifier it uses (its classes: gestures.TASK_CLASSES)
    success: str  # what its success is called in results ("installed", "placed", "screwed")
    obs_frame_dim: int
    obs_dim: int
    act_dim: int

    @property
    def env_id(self) -> str:
        return f"mimicrete/{self.sim}-v0"


def _task(name: str, sim: str, gesture_model: str, success: str) -> TaskSpec:
    d = _CONST["tasks"][sim]
    return TaskSpec(
        name,
        sim,
        gesture_model,
        success,
        int(d["obs_frame_dim"]),
        int(d["obs_dim"]),
        int(d["act_dim"]),
    )


TABLE: dict[str, TaskSpec] = {
    t.name: t
    for t in (
        _task("suction", "TileSuction", "grip", "installed"),
        _task("grip", "BlockGrip", "grip", "placed"),
        _task("screw", "Screw", "screw", "screwed"),
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
