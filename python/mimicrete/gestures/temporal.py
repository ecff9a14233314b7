"""A temporal gesture model: the per-frame features of the last ``W`` frames, summarised, into the
same scaler + RBF SVM (paper §3.2 names a spatio-temporal model as future work; screwing is a
motion, not only a pose).

Why this and not a small 1-D convolution: the per-frame model's whole path stays — the 5-fold CV
grid search, :class:`~mimicrete.gestures.model.FastRbfSvc` (one frame in tens of µs, no torch in
the live loop), its decision margin for the HUD, joblib + JSON persistence — and a user's few
hundred recorded frames per class are an SVM's regime, not a network's.

Window features at frame ``t`` (only frames the model was asked about and whose hand frame is not
degenerate enter the window; the first frames of a stream pad it with the first one), for the
``parts`` of the model (default ``median, delta``):

* ``last``: the frame's own features ``f_t`` (60 numbers: :func:`features_3d`; a one-frame
  tracking glitch shows in it, which is why the default leaves it out);
* ``median``: the per-feature median over the window (one-frame glitches do not move it);
* ``mean``: the per-feature mean over the window;
* ``delta``: the median of the newest ``⌈W/2⌉`` frames minus that of the oldest ``⌈W/2⌉``: how
  the fingers moved relative to the wrist over the window (the hand frame is the wrist's, so
  this is finger motion, not hand travel), robust to a one-frame glitch as the median is.

The stream interface is the per-frame model's: :meth:`TemporalGestureModel.predict_margin` once
per frame in order (it keeps its own window), :meth:`TemporalGestureModel.reset` between
episodes. :meth:`TemporalGestureModel.predict_sequence` gives the same answers for a whole
sequence at once.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .classes import TASK_CLASSES, TASK_MODEL
from .features import features_3d
from .model import GestureModel
from .sequences import GestureSequence, sequence_dataset

DEFAULT_WINDOW = 9  # frames: 0.1 s at 90 Hz
#: Per-frame features that are zero by construction of the hand frame (index proximal's z,
#: middle proximal's x and z): only float rounding (~1e-17) is left in them, which a scaler
#: would blow up to unit variance, so the temporal model sets them to exactly 0.
STRUCTURAL_ZEROS = (3 * 4 + 2, 3 * 8 + 0, 3 * 8 + 2)
DEFAULT_PARTS: tuple[str, ...] = ("median", "delta")
PARTS = ("last", "median", "mean", "delta")
#: C × gamma grid of the temporal SVM (features are 3 × 60 wide, so gamma is smaller).
TEMPORAL_GRID: dict[str, list[Any]] = {
    "svc__C": [1.0, 10.0],
    "svc__gamma": ["scale", 0.003],
}
#: Seeds of the built-in temporal models' training sequences; benchmarks hold out others.
TRAIN_SEEDS = range(0, 12)
#: Seeds of the held-out sequences (``mimicrete gesture eval`` of a temporal model, the benchmark).
HELDOUT_SEEDS = range(1000, 1006)


def window_features(
    feats: np.ndarray, window: int, parts: tuple[str, ...] = DEFAULT_PARTS
) -> np.ndarray:
    """Window features of consecutive per-frame features ``(T, F)`` → ``(T, len(parts) · F)``
    (row ``t`` summarises frames ``t−W+1 … t``, padded at the start with frame 0)."""
    f = np.asarray(feats, dtype=np.float64)
    if len(f) == 0:
        return np.zeros((0, len(parts) * f.shape[-1]))
    padded = np.concatenate([np.repeat(f[:1], window - 1, axis=0), f])
    win = np.lib.stride_tricks.sliding_window_view(padded, window, axis=0)  # (T, F, W)
    return np.concatenate([_part(p, f, win, axis=-1) for p in parts], axis=1)


#: A window's delta this close to 0 is 0: a feature that holds still within a window (a
#: synthetic hand's proportions) differs only by float rounding (~1e-16) between frames, and
#: between the batch and the per-frame computation of the same frame; a scaler would blow that
#: up to unit variance and let one rounding step change the class. Real deltas are above 1e-6.
DELTA_FLOOR = 1e-12


def _part(name: str, last: np.ndarray, win: np.ndarray, axis: int) -> np.ndarray:
    if name == "last":
        return last
    if name == "median":
        return np.median(win, axis=axis)
    if name == "mean":
        return np.mean(win, axis=axis)
    if name == "delta":
        w = win.shape[axis]
        h = (w + 1) // 2
        if axis == -1:
            d = np.median(win[..., w - h :], axis=-1) - np.median(win[..., :h], axis=-1)
        else:
            d = np.median(win[w - h :], axis=0) - np.median(win[:h], axis=0)
        return np.where(np.abs(d) < DELTA_FLOOR, 0.0, d)
    raise ValueError(f"unknown window part {name!r}; known: {PARTS}")


@dataclass
class TemporalGestureModel(GestureModel):
    """A :class:`GestureModel` whose SVM reads window features (module doc); stateful per
    stream. ``window`` frames, ``parts`` as :func:`window_features`."""

    window: int = DEFAULT_WINDOW
    parts: tuple[str, ...] = DEFAULT_PARTS
    _buf: deque = field(default_factory=deque, repr=False, compare=False)

    kind = "temporal"

    def __post_init__(self) -> None:
        if self.window < 1:
            raise ValueError(f"window must be ≥ 1 frame, got {self.window}")
        for p in self.parts:
            if p not in PARTS:
                raise ValueError(f"unknown window part {p!r}; known: {PARTS}")
        if self.dims != 3:
            raise ValueError("the temporal model reads 3-D hand joints")
        self._buf = deque(maxlen=self.window)

    def features(
        self, joints: np.ndarray, handedness: Any = "right", layout: str | None = None
    ) -> np.ndarray:
        """Per-frame features (:func:`features_3d`) with :data:`STRUCTURAL_ZEROS` set to 0."""
        f = super().features(joints, handedness, layout)
        f[..., list(STRUCTURAL_ZEROS)] = 0.0
        return f

    def reset(self) -> None:
        """Forget the window (a new stream: another episode, or the hand came back after long)."""
        self._buf.clear()

    def _stream_input(self, f: np.ndarray) -> np.ndarray:
        """The frame enters the window; the window's features (:meth:`predict_margin`)."""
        self._buf.append(f)
        win = np.stack(self._buf)  # (n ≤ W, F)
        if len(win) < self.window:
            win = np.concatenate([np.repeat(win[:1], self.window - len(win), axis=0), win])
        return np.concatenate([_part(p, f, win, axis=0) for p in self.parts])

    def _sequence_inputs(self, f: np.ndarray) -> np.ndarray:
        """A whole stream's window features at once (:meth:`predict_sequence`)."""
        return window_features(f, self.window, self.parts)

    def predict_one(
        self, joints: np.ndarray, handedness: str = "right", layout: str | None = None
    ) -> str | None:
        """The next frame of the stream: its class (None for a degenerate hand)."""
        return self.predict_margin(joints, handedness, layout)[0]

    def predict(
        self, joints: np.ndarray, handedness: Any = "right", layout: str | None = None
    ) -> np.ndarray:
        """Classes of a batch ``(T, N, 3)`` taken as one sequence from a fresh window
        (degenerate frames give ``None``); does not touch the streaming state."""
        return self.predict_sequence(joints, handedness, layout)

    def score(self, joints: np.ndarray, labels: np.ndarray, handedness: Any = "right") -> float:
        """Accuracy over one sequence."""
        return float(np.mean(self.predict_sequence(joints, handedness) == np.asarray(labels)))

    def spec(self) -> dict[str, Any]:
        s = super().spec()
        n = s["n_features"]
        s.update(
            {
                "kind": "3d-window",
                "window_frames": self.window,
                "window_parts": list(self.parts),
                "per_frame_features": n,
                "n_features": n * len(self.parts),
            }
        )
        return s

    def _state(self) -> dict[str, Any]:
        return {"kind": "temporal", "window": self.window, "parts": list(self.parts)}


# ----------------------------------------------------------------------------------------------
# Fitting
# ----------------------------------------------------------------------------------------------


def sequence_samples(
    sequences: list[GestureSequence],
    *,
    window: int | None,
    parts: tuple[str, ...] = DEFAULT_PARTS,
    stride: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(X, y, groups)`` from sequences: window features (``window`` None: per-frame features)
    of the tracked, non-degenerate frames, every ``stride``-th one, and the sequence index."""
    xs, ys, gs = [], [], []
    for k, s in enumerate(sequences):
        f = features_3d(s.joints, s.layout, s.handedness)
        f[:, list(STRUCTURAL_ZEROS)] = 0.0
        ok = np.all(np.isfinite(f), axis=1) & np.asarray(s.tracked, dtype=bool)
        x = f[ok] if window is None else window_features(f[ok], window, parts)
        y = np.asarray(s.labels)[ok]
        pick = slice(k % stride, None, stride)
        xs.append(x[pick])
        ys.append(y[pick])
        gs.append(np.full(len(y[pick]), k))
    return np.concatenate(xs), np.concatenate(ys), np.concatenate(gs)


def fit_groups(
    x: np.ndarray,
    y: np.ndarray,
    groups: np.ndarray,
    *,
    test_size: float = 0.2,
    seed: int = 0,
    grid: dict[str, list[Any]] | None = None,
    n_jobs: int = 1,
) -> tuple[Any, dict[str, Any], tuple[np.ndarray, np.ndarray]]:
    """Scaler + RBF SVC, C × gamma by 5-fold CV where folds (and the held-out share) are whole
    sequences: frames of one sequence are too alike to test each other.

    Returns:
        ``(pipeline, info, (held-out X, held-out y))``."""
    from sklearn.model_selection import GridSearchCV, GroupKFold, GroupShuffleSplit
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    n_groups = len(np.unique(groups))
    if n_groups < 6:
        raise ValueError(f"need at least 6 sequences (5 CV folds + held out), got {n_groups}")
    tr, te = next(GroupShuffleSplit(1, test_size=test_size, random_state=seed).split(x, y, groups))
    pipe = Pipeline([("scale", StandardScaler()), ("svc", SVC(kernel="rbf"))])
    search = GridSearchCV(pipe, grid or TEMPORAL_GRID, cv=GroupKFold(n_splits=5), n_jobs=n_jobs)
    search.fit(x[tr], y[tr], groups=groups[tr])
    best = search.best_estimator_
    info = {
        "best_params": dict(search.best_params_),
        "cv_accuracy": float(search.best_score_),
        "test_accuracy": float(np.mean(best.predict(x[te]) == y[te])),
        "n_train": int(len(tr)),
        "n_test": int(len(te)),
        "n_sequences": int(n_groups),
        "n_test_sequences": int(len(np.unique(groups[te]))),
        "test_size": test_size,
        "seed": seed,
        "n_support": int(best.named_steps["svc"].n_support_.sum()),
        "grid": {k: list(v) for k, v in (grid or TEMPORAL_GRID).items()},
        "split": "whole sequences (GroupShuffleSplit; 5-fold GroupKFold CV)",
    }
    return best, info, (x[te], y[te])


def fit_temporal(
    sequences: list[GestureSequence],
    task: str = "custom",
    *,
    classes: tuple[str, ...] | None = None,
    window: int = DEFAULT_WINDOW,
    parts: tuple[str, ...] = DEFAULT_PARTS,
    stride: int = 6,
    test_size: float = 0.2,
    seed: int = 0,
    grid: dict[str, list[Any]] | None = None,
    n_jobs: int = 1,
) -> tuple[TemporalGestureModel, tuple[np.ndarray, np.ndarray]]:
    """Fit a :class:`TemporalGestureModel` on labelled sequences (every ``stride``-th frame of
    each is a training sample; consecutive frames at 90 Hz add little). Returns the model and
    its held-out ``(window features, labels)`` (whole sequences it never saw)."""
    x, y, groups = sequence_samples(sequences, window=window, parts=parts, stride=stride)
    pipe, info, held = fit_groups(
        x, y, groups, test_size=test_size, seed=seed, grid=grid, n_jobs=n_jobs
    )
    info["stride"] = stride
    layout = sequences[0].layout
    classes = classes or TASK_CLASSES.get(task) or tuple(sorted(set(y.tolist())))
    model = TemporalGestureModel(
        pipe, tuple(classes), layout, 3, task, info, window=window, parts=tuple(parts)
    )
    return model, held


def fit_per_frame_on_sequences(
    sequences: list[GestureSequence],
    task: str = "custom",
    *,
    stride: int = 6,
    test_size: float = 0.2,
    seed: int = 0,
    grid: dict[str, list[Any]] | None = None,
    n_jobs: int = 1,
) -> GestureModel:
    """The per-frame SVM fitted on the same frames as :func:`fit_temporal` (a control: what the
    sequences' data alone do, without the window)."""
    x, y, groups = sequence_samples(sequences, window=None, stride=stride)
    pipe, info, _ = fit_groups(
        x, y, groups, test_size=test_size, seed=seed, grid=grid, n_jobs=n_jobs
    )
    info["stride"] = stride
    classes = TASK_CLASSES.get(task) or tuple(sorted(set(y.tolist())))
    return GestureModel(pipe, tuple(classes), sequences[0].layout, 3, task, info)


def train_temporal_builtin(
    task: str,
    seeds: range | list[int] = TRAIN_SEEDS,
    *,
    window: int = DEFAULT_WINDOW,
    parts: tuple[str, ...] = DEFAULT_PARTS,
    stride: int = 6,
    grid: dict[str, list[Any]] | None = None,
    n_jobs: int = 1,
) -> tuple[TemporalGestureModel, tuple[np.ndarray, np.ndarray]]:
    """The temporal model of ``task`` (``grip``/``suction``/``screw``) on the built-in sequences:
    demonstrator episodes and drills (:mod:`mimicrete.gestures.sequences`) of ``seeds``; and its
    held-out ``(window features, labels)``."""
    task = TASK_MODEL.get(task, task)
    seqs = sequence_dataset(task, seeds)
    model, held = fit_temporal(
        seqs, task, window=window, parts=parts, stride=stride, grid=grid, n_jobs=n_jobs
    )
    model.info["data"] = (
        f"builtin sequences: demonstrator episodes + drills, seeds {list(seeds)[0]}.."
        f"{list(seeds)[-1]}"
    )
    return model, held
