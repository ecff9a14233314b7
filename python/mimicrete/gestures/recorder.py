"""Record labelled gesture samples from a live hand, class by class, into the labelled CSV that
``mimicrete gesture train`` reads, and train on them (5-fold CV as the paper).

Push style, for a server that receives frames as they come (:class:`GestureRecorder`)::

    rec = GestureRecorder(("closing", "opening", "fixed"), per_class=150, layout="webxr")
    rec.start("closing")             # ask the user for the gesture, then feed frames:
    rec.push(t, tracked, joints)     # per hand frame; True when the frame became a sample
    rec.progress()                   # {"current", "counts", "target", "done"} for the page
    rec.start("closing")             # redo: that class's samples are dropped, a new take begins
    rec.write_csv("gestures.csv")    # header form: label,sequence,t,handedness,coords…
    model, report = train_samples(*rec.samples(), layout="webxr")

Pull style, for a scripted source (:func:`record`): a :class:`FrameSource` is prompted for each
class of a schedule and its frames are fed until the class has its samples.

Which frames become samples: tracked, non-degenerate hands only; none in the first
``settle_s`` after a class starts (the hand is still forming the gesture); at most one per
``min_interval_s`` (consecutive 90 Hz frames are nearly the same sample). Each take of a class
is one ``sequence`` in the CSV.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from .data import write_gesture_csv
from .features import features_3d
from .model import GestureModel, fit


class FrameSource(Protocol):
    """Where frames come from: ``prompt(label)`` asks for a gesture (a page shows it; an
    emulator sets the pose), ``frames()`` yields ``(t, tracked, joints)`` as they arrive."""

    def prompt(self, label: str) -> None: ...

    def frames(self) -> Iterator[tuple[float, bool, np.ndarray]]: ...


@dataclass
class GestureRecorder:
    """Collects samples per class (module doc).

    Args:
        classes: the class names, in the order they are usually asked.
        per_class: target samples per class.
        layout: joint order of the frames (``webxr`` from the page).
        handedness: the hand recorded.
        settle_s: seconds after a class starts before samples are kept.
        min_interval_s: least time between two kept samples.
    """

    classes: tuple[str, ...]
    per_class: int = 150
    layout: str = "webxr"
    handedness: str = "right"
    settle_s: float = 0.5
    min_interval_s: float = 0.05
    current: str | None = None
    _rows: dict[str, list[tuple[int, float, np.ndarray]]] = field(default_factory=dict)
    _take: int = 0
    _t_start: float | None = None
    _t_last: float | None = None

    def __post_init__(self) -> None:
        self.classes = tuple(self.classes)
        if len(set(self.classes)) != len(self.classes) or not self.classes:
            raise ValueError(f"classes must be distinct and not empty: {self.classes}")
        if self.per_class < 1:
            raise ValueError("per_class must be ≥ 1")
        self._rows = {c: [] for c in self.classes}

    def start(self, label: str) -> None:
        """Start (or redo) ``label``: its earlier samples are dropped and a new take begins."""
        if label not in self._rows:
            raise ValueError(f"unknown class {label!r}; classes: {self.classes}")
        self.current = label
        self._rows[label] = []
        self._take += 1
        self._t_start = self._t_last = None

    def stop(self) -> None:
        """Stop recording (frames are ignored until the next :meth:`start`)."""
        self.current = None

    def push(self, t: float, tracked: bool, joints: np.ndarray) -> bool:
        """Feed one frame; returns whether it became a sample of the current class."""
        label = self.current
        if label is None or not tracked or len(self._rows[label]) >= self.per_class:
            return False
        t = float(t)
        if self._t_start is None:
            self._t_start = t
        if t < self._t_start + self.settle_s:
            return False
        if self._t_last is not None and t < self._t_last + self.min_interval_s:
            return False
        j = np.array(joints, dtype=np.float64)
        if not np.all(np.isfinite(features_3d(j, self.layout, self.handedness))):
            return False
        self._rows[label].append((self._take, t, j))
        self._t_last = t
        return True

    def count(self, label: str) -> int:
        return len(self._rows[label])

    def done(self, label: str | None = None) -> bool:
        """Whether ``label`` (default: every class) has its target count."""
        labels = [label] if label is not None else list(self.classes)
        return all(self.count(c) >= self.per_class for c in labels)

    def progress(self) -> dict[str, Any]:
        """``{"current", "counts": {class: n}, "target", "done"}`` (JSON-ready)."""
        return {
            "current": self.current,
            "counts": {c: self.count(c) for c in self.classes},
            "target": self.per_class,
            "done": self.done(),
        }

    def samples(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(labels (n,), joints (n, N, 3), sequence (n,) take ids, t (n,))``, class by class."""
        labels, joints, seq, ts = [], [], [], []
        for c in self.classes:
            for take, t, j in self._rows[c]:
                labels.append(c)
                joints.append(j)
                seq.append(take)
                ts.append(t)
        if not labels:
            raise ValueError("no samples recorded")
        return np.array(labels), np.array(joints), np.array(seq), np.array(ts)

    def write_csv(self, path: str | Path) -> Path:
        """Write the samples as a labelled CSV (header form: ``label,sequence,t,handedness``,
        then the coordinates; ``mimicrete gesture train --data`` reads it)."""
        labels, joints, seq, ts = self.samples()
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        write_gesture_csv(path, labels, joints, sequence=seq, t=ts, handedness=self.handedness)
        return path


def record(
    source: FrameSource,
    schedule: list[tuple[str, int]] | tuple[tuple[str, int], ...],
    *,
    layout: str = "webxr",
    handedness: str = "right",
    settle_s: float = 0.5,
    min_interval_s: float = 0.05,
    max_frames_per_class: int = 100_000,
) -> GestureRecorder:
    """Record each ``(class, count)`` of ``schedule`` in turn from ``source``.

    Raises:
        RuntimeError: the source ran out of frames, or a class did not fill within
            ``max_frames_per_class`` frames.
    """
    classes = tuple(dict.fromkeys(c for c, _ in schedule))
    target = max(n for _, n in schedule)
    rec = GestureRecorder(
        classes, target, layout, handedness, settle_s=settle_s, min_interval_s=min_interval_s
    )
    for label, n in schedule:
        rec.start(label)
        source.prompt(label)
        seen = 0
        for t, tracked, joints in source.frames():
            rec.push(t, tracked, joints)
            seen += 1
            if rec.count(label) >= n:
                break
            if seen >= max_frames_per_class:
                raise RuntimeError(f"{label}: {rec.count(label)}/{n} samples after {seen} frames")
        else:
            raise RuntimeError(f"{label}: the source ended at {rec.count(label)}/{n} samples")
    rec.stop()
    return rec


def train_samples(
    labels: np.ndarray,
    joints: np.ndarray,
    sequence: np.ndarray | None = None,
    t: np.ndarray | None = None,
    *,
    layout: str = "webxr",
    handedness: str = "right",
    test_size: float = 0.2,
    seed: int = 0,
    grid: dict[str, list[Any]] | None = None,
) -> tuple[GestureModel, dict[str, Any]]:
    """Fit a per-frame model on recorded samples (stratified split, 5-fold CV grid search, as
    ``mimicrete gesture train --data``). Returns it and a JSON-ready report: ``classes``,
    ``cv_accuracy``, ``test_accuracy``, ``n_train``, ``n_test``, ``confusion`` (rows truth,
    columns prediction, in ``classes`` order)."""
    del sequence, t  # the per-frame model reads each sample alone
    labels = np.asarray(labels)
    feats = features_3d(joints, layout, handedness)
    pipe, info, (xte, yte) = fit(feats, labels, test_size=test_size, seed=seed, grid=grid)
    classes = tuple(dict.fromkeys(labels.tolist()))
    pred = pipe.predict(xte)
    idx = {c: i for i, c in enumerate(classes)}
    conf = np.zeros((len(classes), len(classes)), dtype=int)
    for a, b in zip(yte, pred, strict=True):
        conf[idx[str(a)], idx[str(b)]] += 1
    info["data"] = "recorded samples"
    model = GestureModel(pipe, classes, layout, 3, "custom", info)
    report = {
        "classes": list(classes),
        "cv_accuracy": info["cv_accuracy"],
        "test_accuracy": info["test_accuracy"],
        "n_train": info["n_train"],
        "n_test": info["n_test"],
        "confusion": conf.tolist(),
    }
    return model, report
