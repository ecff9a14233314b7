"""The gesture classes of each task and the paper's numbers about them (§3.2, Table 1)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mimicrete import tasks
from mimicrete._native import MimicreteError

#: The classes of each gesture model (``grip``, ``screw``); which model a task uses is the task
#: table's (:attr:`mimicrete.tasks.TaskSpec.gesture_model`, :data:`TASK_MODEL`).
TASK_CLASSES: dict[str, tuple[str, ...]] = {
    "grip": ("closing", "opening", "fixed"),
    "screw": (
        "closing_tightening",
        "closing_loosening",
        "closing_fixed",
        "opening_stopped",
        "fixed_stopped",
    ),
}
#: Which finger shape (:data:`mimicrete.hands.model.GESTURE_SHAPES`) shows each class (the
#: typical one: the scripted demonstrator's and the drills'; training draws from
#: :data:`CLASS_FAMILIES`).
CLASS_SHAPE: dict[str, str] = {
    "closing": "closing",
    "opening": "opening",
    "fixed": "fixed",
    "closing_tightening": "tightening",
    "closing_loosening": "loosening",
    "closing_fixed": "closing",
    "opening_stopped": "opening",
    "fixed_stopped": "fixed",
}
#: Which shape families (:data:`mimicrete.hands.model.GESTURE_RANGES`) the built-in training
#: hands of each class are drawn from. For the 3-class model every pinch is ``closing`` (the
#: screwing tuples' gripping half: closing with the other fingers loose or curled).
CLASS_FAMILIES: dict[str, tuple[str, ...]] = {
    "closing": ("closing", "tightening", "loosening"),
    "opening": ("opening",),
    "fixed": ("fixed",),
    "closing_tightening": ("tightening",),
    "closing_loosening": ("loosening",),
    "closing_fixed": ("closing",),
    "opening_stopped": ("opening",),
    "fixed_stopped": ("fixed",),
}
#: Paper §3.2: samples per class and the held-out share.
PAPER_COUNTS: dict[str, tuple[int, ...]] = {
    "grip": (290, 274, 263),
    "screw": (1475, 1289, 1494, 1209, 1458),
}
PAPER_TEST_SIZE: dict[str, float] = {"grip": 0.2, "screw": 0.3}
#: Paper Table 1: held-out accuracy.
PAPER_ACCURACY: dict[str, float] = {"grip": 0.9819, "screw": 0.9928}
#: Task names the rest of the package uses → gesture model (from :data:`mimicrete.tasks.TABLE`).
TASK_MODEL: dict[str, str] = {t.name: t.gesture_model for t in tasks.TABLE.values()}

DEFAULT_GRID: dict[str, list[Any]] = {
    "svc__C": [0.3, 1.0, 10.0, 100.0],
    "svc__gamma": ["scale", 0.001, 0.003, 0.01, 0.03],
}
#: Which kind of model ``load_default`` gives per model task: ``per-frame`` (the paper's SVM on
#: one frame) or ``temporal`` (:mod:`mimicrete.gestures.temporal`). Chosen by
#: ``python -m mimicrete.bench gestures`` (numbers in :mod:`mimicrete.bench.gestures`): after
#: the session's smoother the two tie on flicker, latency and accuracy on held-out demonstrator
#: sequences, and the per-frame model costs a third per frame and keeps no state, so it stays
#: the default for both tasks.
DEFAULT_KIND: dict[str, str] = {"grip": "per-frame", "screw": "per-frame"}
MODELS_DIR = Path(__file__).resolve().parent / "models"
"""The shipped models (trained on the built-in synthetic hands only, tested on captured ones;
remade by ``python -m mimicrete.gestures.shipped``, see ``models/README.md``)."""


class GestureDataError(MimicreteError, ValueError):
    """A gesture CSV is malformed; the message starts with ``file:line:``."""
