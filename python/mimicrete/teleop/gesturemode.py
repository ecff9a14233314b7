"""The gesture mode of the live page: teach the gesture SVM your own hand (issue 14).

The page asks for each class of the task in turn (suction / grip: ``closing``, ``opening``,
``fixed``; screw: the paper's five tuples). While a class records, every usable right-hand frame
that arrives at least ``min_interval_s`` after the previous sample (and ``settle_s`` after the
class started, while the hand forms the gesture) becomes a labelled sample
(:class:`mimicrete.gestures.recorder.GestureRecorder`); the user holds the gesture and moves and
turns the hand about the workspace. A class can be redone. When every class has its samples the
server trains, in a worker thread (the frame loop keeps running): it writes the labelled CSV that
``mimicrete gesture train --data`` reads (``label,sequence,t,handedness`` + 75 WebXR coordinates)
to ``DIR/gesture_<task>_user.csv``, fits the per-frame SVM with a stratified 80/20 split and a
5-fold CV grid search (:func:`mimicrete.gestures.recorder.train_samples`), and saves it as
``DIR/gesture_<task>_user.joblib`` (+ ``.json``). The live session uses it from then on, and the
next ``mimicrete teleop --out DIR`` picks it up (:func:`user_model_path`).

No networking and no event loop here: :class:`~.live.Live` feeds frames and applies a finished
training on its own thread (:meth:`GestureMode.finished`).
"""

from __future__ import annotations

import os
import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import tasks
from mimicrete._native import MimicreteError
from mimicrete.gestures import (
    TASK_CLASSES,
    TASK_MODEL,
    GestureModel,
    read_gesture_csv,
    write_gesture_csv,
)
from mimicrete.gestures.recorder import GestureRecorder, train_samples

from .provenance import file_sha256

#: Samples per class unless the page or the CLI asks for another count.
DEFAULT_PER_CLASS = 150
#: Fewest samples per class a training accepts (an 80/20 split leaves 5-fold CV ≥ 6 per class).
MIN_PER_CLASS = 10
LAYOUT = "webxr"
HANDEDNESS = "right"

#: What each class makes the end effector do, per end effector (the suction head, the gripper)
#: and for the screw's gesture model, and a gesture to try for it (the user may choose any hand
#: shape, as long as the classes differ and each is held the same way); which one a task shows
#: is :func:`task_prompts`'s.
PROMPTS: dict[str, dict[str, tuple[str, str]]] = {
    "suction": {
        "closing": ("suction on (pick the tile)", "a fist or a pinch"),
        "opening": ("suction off (drop)", "an open, relaxed hand"),
        "fixed": ("hold: the suction stays as it is", "point with the index"),
    },
    "gripper": {
        "closing": ("close the gripper", "a fist or a pinch"),
        "opening": ("open the gripper", "an open, relaxed hand"),
        "fixed": ("hold: the gripper stays as it is", "point with the index"),
    },
    "screw": {
        "closing_tightening": ("gripper closed, screw in", "a fist, thumb straight out"),
        "closing_loosening": ("gripper closed, screw out", "a fist, little finger out"),
        "closing_fixed": ("gripper closed, no turning", "a fist"),
        "opening_stopped": ("gripper open, no turning", "an open hand"),
        "fixed_stopped": ("hold everything", "point with the index"),
    },
}


def user_model_path(out: str | Path, task: str) -> Path:
    """Where the gesture mode saves the model it trains for ``task`` in the demo folder ``out``."""
    return Path(out) / f"gesture_{task}_user.joblib"


def user_csv_path(out: str | Path, task: str) -> Path:
    """Where the gesture mode writes the labelled samples it trains on."""
    return Path(out) / f"gesture_{task}_user.csv"


def task_prompts(task: str) -> dict[str, tuple[str, str]]:
    """The :data:`PROMPTS` of a task of the table, from its spec: the screw's for its 5-class
    gesture model, else its end effector's (the row's: the suction head's)."""
    t = tasks.get(task)
    return PROMPTS["screw" if t.gesture_model == "screw" else t.effector]


def task_classes(task: str) -> tuple[str, ...]:
    """The gesture classes of a teleoperation task (``suction``/``grip``/``screw``)."""
    return TASK_CLASSES[TASK_MODEL[task]]


class GestureModeError(MimicreteError, ValueError):
    """A gesture-mode request that cannot be done now (the message says why)."""


class GestureMode:
    """Samples of each class, and the training on them (module doc).

    Args:
        task: ``suction`` / ``grip`` / ``screw``.
        out: the demo folder (the CSV and the model are written there).
        per_class: samples per class.
        settle_s, min_interval_s: see :class:`~mimicrete.gestures.recorder.GestureRecorder`.
        grid: the C × gamma grid of the SVM's 5-fold CV search (default: the full one).
    """

    def __init__(
        self,
        task: str,
        out: str | Path,
        per_class: int = DEFAULT_PER_CLASS,
        *,
        settle_s: float = 0.5,
        min_interval_s: float = 0.05,
        grid: dict[str, list[Any]] | None = None,
    ) -> None:
        self.task = task
        self.out = Path(out)
        self.classes = task_classes(task)
        self.prompts = task_prompts(task)
        self.recorder = GestureRecorder(
            self.classes,
            check_per_class(per_class),
            LAYOUT,
            HANDEDNESS,
            settle_s=settle_s,
            min_interval_s=min_interval_s,
        )
        self.grid = grid
        self.report: dict[str, Any] | None = None
        self.error: str | None = None
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="teleop-gestures")
        self._future: Future[tuple[GestureModel, dict[str, Any]]] | None = None
        #: frames pushed while a training ran (the frame loop is not held up by it)
        self.frames_while_training = 0

    # ------------------------------------------------------------------ recording

    @property
    def per_class(self) -> int:
        return self.recorder.per_class

    @per_class.setter
    def per_class(self, n: int) -> None:
        self.recorder.per_class = check_per_class(n)

    @property
    def current(self) -> str | None:
        return self.recorder.current

    @property
    def training(self) -> bool:
        return self._future is not None

    def next_class(self) -> str | None:
        """The first class, in the task's order, that does not have its samples yet."""
        return next((c for c in self.classes if not self.recorder.done(c)), None)

    def record(self, label: str | None = None) -> str:
        """Start (or redo: its samples are dropped) ``label``, default the next class."""
        label = label or self.next_class() or self.classes[0]
        if label not in self.classes:
            raise GestureModeError(f"unknown class {label!r}; {self.task} has {self.classes}")
        self.recorder.start(label)
        return label

    def pause(self) -> None:
        """Stop recording; the class keeps the samples it has."""
        self.recorder.stop()

    def push(self, t: float, tracked: bool, joints: np.ndarray) -> str | None:
        """One right-hand frame. Returns None (no sample), ``"sample"`` or ``"class_done"`` (this
        sample filled the class; recording stops)."""
        if self.training:
            self.frames_while_training += 1
        label = self.recorder.current
        if label is None or not self.recorder.push(t, tracked, joints):
            return None
        if self.recorder.done(label):
            self.recorder.stop()
            return "class_done"
        return "sample"

    # ------------------------------------------------------------------ training

    def train(self) -> Future[tuple[GestureModel, dict[str, Any]]]:
        """Write the CSV, fit and save the model, in the worker thread (returns its future)."""
        if self._future is not None:
            raise GestureModeError("a training is already running")
        few = [
            f"{c} ({self.recorder.count(c)})"
            for c in self.classes
            if self.recorder.count(c) < MIN_PER_CLASS
        ]
        if few:
            raise GestureModeError(
                f"every class needs at least {MIN_PER_CLASS} samples to train: {', '.join(few)}"
            )
        self.recorder.stop()
        labels, joints, seq, ts = self.recorder.samples()  # a copy: recording may go on
        self.error = None
        self.frames_while_training = 0
        self._future = self._pool.submit(self._train, labels, joints, seq, ts)
        return self._future

    def finished(self) -> tuple[GestureModel | None, str | None]:
        """A training that has ended: ``(model, None)``, or ``(None, error)``; ``(None, None)``
        while none has ended since the last call."""
        f = self._future
        if f is None or not f.done():
            return None, None
        self._future = None
        try:
            model, report = f.result()
        except Exception as e:  # shown in the page; the model in use stays
            self.error = f"training failed: {e}"
            return None, self.error
        self.report = report
        return model, None

    def _train(
        self, labels: np.ndarray, joints: np.ndarray, seq: np.ndarray, ts: np.ndarray
    ) -> tuple[GestureModel, dict[str, Any]]:
        t0 = time.perf_counter()
        self.out.mkdir(parents=True, exist_ok=True)
        csv = user_csv_path(self.out, self.task)
        tmp_csv = csv.with_name(csv.name + ".tmp")
        write_gesture_csv(tmp_csv, labels, joints, sequence=seq, t=ts, handedness=HANDEDNESS)
        os.replace(tmp_csv, csv)
        # trained on the CSV as written (its 6 significant digits), so that `mimicrete gesture
        # train --data` gives the same model: a feature that hardly varies (an emulated hand's
        # fixed pose) is scaled up by its tiny spread, and the rounding would otherwise move
        # the CSV's samples away from the ones trained on
        data = read_gesture_csv(csv, LAYOUT)
        labels = data.labels
        model, report = train_samples(
            data.labels, data.joints, layout=LAYOUT, handedness=HANDEDNESS, grid=self.grid
        )
        model.info.update(
            data=str(csv),
            recorded_with="mimicrete teleop --gestures",
            teleop_task=self.task,
            handedness=HANDEDNESS,
            samples_per_class={c: int(np.sum(labels == c)) for c in self.classes},
        )
        path = user_model_path(self.out, self.task)
        tmp = path.with_name(path.stem + ".tmp.joblib")
        model.save(tmp)
        sha = file_sha256(tmp)  # what the hand logs name it by (not in the sidecar either)
        os.replace(str(tmp) + ".json", str(path) + ".json")
        os.replace(tmp, path)
        model.info["path"] = str(path)  # not in the sidecar: the folder may move
        model.info["sha256"] = sha
        report.update(csv=str(csv), model=str(path), seconds=time.perf_counter() - t0)
        return model, report

    # ------------------------------------------------------------------ out

    def status(self) -> dict[str, Any]:
        """What the page shows (the ``gestures`` message's fields but ``type``, ``event``,
        ``active`` and ``model``)."""
        rec = self.recorder
        return {
            "task": self.task,
            "classes": list(self.classes),
            "prompts": {c: {"meaning": m, "try": s} for c, (m, s) in self.prompts.items()},
            "target": rec.per_class,
            "counts": {c: rec.count(c) for c in self.classes},
            "current": rec.current,
            "next": self.next_class(),
            "training": self.training,
            "report": self.report,
            "error": self.error,
        }

    def close(self) -> None:
        self._pool.shutdown(wait=True)


def check_per_class(n: Any) -> int:
    """A per-class target from the page or the CLI: an integer in 10 … 5000."""
    if isinstance(n, bool) or not isinstance(n, int | float) or int(n) != n:
        raise GestureModeError(f"per_class must be an integer, got {n!r}")
    if not MIN_PER_CLASS <= int(n) <= 5000:
        raise GestureModeError(f"per_class must be in {MIN_PER_CLASS}..5000, got {int(n)}")
    return int(n)
