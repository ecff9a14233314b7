"""A fitted gesture model (scaler + RBF SVM), its fast per-frame path, saving/loading, and fitting
(5-fold CV grid search as the paper)."""

from __future__ import annotations

import json
import math
import platform
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .classes import (
    DEFAULT_GRID,
    PAPER_ACCURACY,
    PAPER_TEST_SIZE,
    TASK_CLASSES,
    TASK_MODEL,
    GestureDataError,
)
from .data import synthetic_dataset
from .features import features_3d, featurize


def _versions() -> dict[str, str]:
    import joblib
    import sklearn

    return {
        "sklearn": sklearn.__version__,
        "numpy": np.__version__,
        "joblib": joblib.__version__,
        "python": platform.python_version(),
    }


@dataclass
class GestureModel:
    """A fitted gesture classifier and what it expects as input.

    Attributes:
        pipeline: ``StandardScaler → SVC(rbf)`` fitted on features.
        classes: class names.
        layout: joint order of the input.
        dims: 3 (x,y,z hand joints) or 2 (image landmarks).
        task: ``grip``, ``screw`` or ``custom``.
        info: training facts (grid-search result, accuracies, split, versions).
    """

    pipeline: Any
    classes: tuple[str, ...]
    layout: str
    dims: int
    task: str = "custom"
    info: dict[str, Any] = field(default_factory=dict)
    _fast: Any = field(default=None, repr=False, compare=False)

    #: ``per-frame`` (each frame on its own) or ``temporal`` (a window of frames; stateful).
    kind = "per-frame"

    def reset(self) -> None:
        """Start a new stream of frames (nothing to forget for a per-frame model)."""

    def predict_sequence(
        self,
        joints: np.ndarray,
        handedness: Any = "right",
        layout: str | None = None,
        tracked: np.ndarray | None = None,
    ) -> np.ndarray:
        """Classes of consecutive frames ``(T, N, dims)`` of one stream (object array; ``None``
        where the frame is untracked — not asked — or degenerate), the same as
        :meth:`predict_margin` frame by frame (after :meth:`reset`)."""
        f = self.features(np.asarray(joints), handedness, layout)
        ok = np.all(np.isfinite(f), axis=1)
        if tracked is not None:
            ok &= np.asarray(tracked, dtype=bool)
        out = np.full(len(f), None, dtype=object)
        if ok.any():
            out[ok] = self.pipeline.predict(self._sequence_inputs(f[ok]))
        return out

    def _sequence_inputs(self, f: np.ndarray) -> np.ndarray:
        """The SVM's inputs for the usable frames' features ``f`` of one stream, in order."""
        return f

    def _stream_input(self, f: np.ndarray) -> np.ndarray:
        """The SVM's input for the next usable frame's features ``f`` of the stream."""
        return f

    def _fast_svc(self) -> Any:
        """:class:`FastRbfSvc` of the pipeline, made once; False when it is not scaler + RBF."""
        if self._fast is None:
            self._fast = FastRbfSvc.from_pipeline(self.pipeline) or False
        return self._fast

    def _state(self) -> dict[str, Any]:
        """What :meth:`save` stores besides the pipeline and the input description."""
        return {"kind": "per-frame"}

    def features(
        self, joints: np.ndarray, handedness: Any = "right", layout: str | None = None
    ) -> np.ndarray:
        """Features of ``joints`` (in ``layout``, default the model's) as this model expects."""
        return featurize(joints, layout or self.layout, self.dims, handedness)

    def predict(
        self, joints: np.ndarray, handedness: Any = "right", layout: str | None = None
    ) -> np.ndarray:
        """Class names for a batch ``(B, N, dims)`` of hands (``layout`` default: the model's;
        3-D models accept every layout, since features use the 21 landmarks all layouts share)."""
        return self.pipeline.predict(self.features(joints, handedness, layout))

    def predict_one(
        self, joints: np.ndarray, handedness: str = "right", layout: str | None = None
    ) -> str | None:
        """Class name of one hand ``(N, dims)``; ``None`` when the hand frame is degenerate.

        Uses :class:`FastRbfSvc` (the same decision as the fitted pipeline, without
        scikit-learn's per-call overhead) when the pipeline is a scaler + RBF SVC."""
        f = self.features(joints, handedness, layout)
        if not np.all(np.isfinite(f)):
            return None
        fast = self._fast_svc()
        if fast:
            return fast.predict_one(f)
        return str(self.pipeline.predict(f[None])[0])

    def predict_margin(
        self, joints: np.ndarray, handedness: str = "right", layout: str | None = None
    ) -> tuple[str | None, float | None]:
        """:meth:`predict_one` and the decision margin of the class it gives
        (:meth:`FastRbfSvc.decide`; None when the model is not a scaler + RBF SVC or the hand is
        degenerate; a degenerate hand does not enter a temporal model's window)."""
        f = self.features(joints, handedness, layout)
        if not np.all(np.isfinite(f)):
            return None, None
        x = self._stream_input(f)
        fast = self._fast_svc()
        if fast:
            return fast.decide(x)
        return str(self.pipeline.predict(x[None])[0]), None

    def score(self, joints: np.ndarray, labels: np.ndarray, handedness: Any = "right") -> float:
        """Accuracy on labelled hands."""
        return float(np.mean(self.predict(joints, handedness) == np.asarray(labels)))

    def spec(self) -> dict[str, Any]:
        """The feature specification stored beside the model."""
        return {
            "kind": f"{self.dims}d",
            "layout": self.layout,
            "landmarks": "canonical21 (MediaPipe order)",
            "frame": (
                "wrist origin, y=wrist->middle proximal, z=(mid-idx)xy, left hands z-mirrored, "
                "scaled by |wrist->middle proximal|"
                if self.dims == 3
                else "wrist-relative, rotated wrist->middle MCP onto +y, scaled by its length"
            ),
            "n_features": 60 if self.dims == 3 else 40,
        }

    def save(self, path: str | Path) -> Path:
        """Write ``path`` (joblib) and ``path.json`` (versions, ``kind`` per-frame/temporal,
        feature spec, training facts). Files without ``kind`` (written before temporal models
        existed) are per-frame."""
        import joblib

        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        joblib.dump(
            {
                "pipeline": self.pipeline,
                "classes": list(self.classes),
                "layout": self.layout,
                "dims": self.dims,
                "task": self.task,
                **self._state(),
            },
            path,
            compress=3,
        )
        sidecar = {
            "format": "mimicrete.gesture_model",
            "version": 1,
            "versions": _versions(),
            "kind": self.kind,
            "task": self.task,
            "classes": list(self.classes),
            "features": self.spec(),
            "info": self.info,
        }
        Path(str(path) + ".json").write_text(json.dumps(sidecar, indent=2) + "\n")
        return path


class FastRbfSvc:
    """Single-sample prediction of a fitted ``StandardScaler → SVC(kernel="rbf")`` pipeline.

    Evaluates the same one-vs-one decision functions from the fitted support vectors, dual
    coefficients and intercepts (libsvm's layout as scikit-learn exposes it: for the pair of
    classes ``i < j`` the coefficients of class ``i``'s support vectors sit in row ``j − 1`` and
    those of class ``j``'s in row ``i``) and votes, ties going to the lower class index as in
    libsvm. About 20× faster than ``pipeline.predict`` on one sample.
    """

    def __init__(self, mean, scale, sv, gamma, dual, intercept, n_support, classes) -> None:
        self.mean, self.scale = np.asarray(mean), np.asarray(scale)
        self.sv = np.ascontiguousarray(sv, dtype=np.float64)
        self.sv_sq = np.einsum("ij,ij->i", self.sv, self.sv)
        self.gamma = float(gamma)
        self.dual = np.asarray(dual, dtype=np.float64)
        self.intercept = np.asarray(intercept, dtype=np.float64)
        self.classes = [str(c) for c in classes]
        starts = np.concatenate([[0], np.cumsum(n_support)]).astype(np.int64)
        self.starts = starts[:-1]
        n = len(self.classes)
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]  # libsvm's pair order
        self.pi = np.array([i for i, _ in pairs], dtype=np.int64)
        self.pj = np.array([j for _, j in pairs], dtype=np.int64)

    @staticmethod
    def from_pipeline(pipe: Any) -> FastRbfSvc | None:
        """Build from a fitted pipeline, or ``None`` when it is not scaler + RBF SVC."""
        try:
            scaler, svc = pipe.named_steps["scale"], pipe.named_steps["svc"]
        except (AttributeError, KeyError):
            return None
        if getattr(svc, "kernel", None) != "rbf" or not hasattr(svc, "support_vectors_"):
            return None
        return FastRbfSvc(
            scaler.mean_,
            scaler.scale_,
            svc.support_vectors_,
            svc._gamma,
            svc.dual_coef_,
            svc.intercept_,
            svc.n_support_,
            svc.classes_,
        )

    def votes(self, features: np.ndarray) -> np.ndarray:
        """One-vs-one votes per class for one feature vector."""
        return self._votes(self._decisions(features))

    def decide(self, features: np.ndarray) -> tuple[str, float]:
        """The class of one feature vector and its margin: the smallest one-vs-one decision
        value of the winner against another class (how far the sample is from the nearest
        boundary that would take a vote away; > 1 is beyond the SVM's margin)."""
        dec = self._decisions(features)
        w = int(np.argmax(self._votes(dec)))
        own = np.concatenate([dec[self.pi == w], -dec[self.pj == w]])
        return self.classes[w], float(own.min())

    def _votes(self, dec: np.ndarray) -> np.ndarray:
        winners = np.where(dec > 0, self.pi, self.pj)
        return np.bincount(winners, minlength=len(self.classes))

    def _decisions(self, features: np.ndarray) -> np.ndarray:
        x = (np.asarray(features, dtype=np.float64) - self.mean) / self.scale
        d2 = self.sv_sq - 2.0 * (self.sv @ x) + x @ x
        k = np.exp(-self.gamma * np.maximum(d2, 0.0))
        # part[r, c]: row r of the dual coefficients against class c's support vectors
        part = np.add.reduceat(self.dual * k, self.starts, axis=1)
        return part[self.pj - 1, self.pi] + part[self.pi, self.pj] + self.intercept

    def predict_one(self, features: np.ndarray) -> str:
        """The class of one feature vector."""
        return self.classes[int(np.argmax(self.votes(features)))]


def fit(
    features: np.ndarray,
    labels: np.ndarray,
    *,
    test_size: float,
    seed: int = 0,
    grid: dict[str, list[Any]] | None = None,
    n_jobs: int = 1,
) -> tuple[Any, dict[str, Any], tuple[np.ndarray, np.ndarray]]:
    """Stratified split, 5-fold CV grid search of an RBF SVC on the training part.

    Returns:
        ``(pipeline, info, (test_features, test_labels))``: ``info`` holds the best parameters,
        the CV accuracy, the held-out accuracy and the split sizes.
    """
    from sklearn.model_selection import GridSearchCV, StratifiedKFold, train_test_split
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler
    from sklearn.svm import SVC

    ok = np.all(np.isfinite(features), axis=1)
    features, labels = features[ok], np.asarray(labels)[ok]
    classes, counts = np.unique(labels, return_counts=True)
    if len(classes) < 2:
        raise GestureDataError(
            f"need at least 2 gesture classes to train, got {len(classes)} "
            f"({', '.join(map(str, classes)) or 'none'})"
        )
    need = math.ceil(5 / (1.0 - test_size)) + 1  # 5 CV folds of the training part, and a test
    few = [f"{c} ({n})" for c, n in zip(classes, counts, strict=True) if n < need]
    if few:
        raise GestureDataError(
            f"each class needs at least {need} usable samples for 5-fold CV, got {', '.join(few)}"
        )
    xtr, xte, ytr, yte = train_test_split(
        features, labels, test_size=test_size, random_state=seed, stratify=labels
    )
    pipe = Pipeline([("scale", StandardScaler()), ("svc", SVC(kernel="rbf"))])
    search = GridSearchCV(
        pipe,
        grid or DEFAULT_GRID,
        cv=StratifiedKFold(n_splits=5, shuffle=True, random_state=seed),
        n_jobs=n_jobs,
    )
    search.fit(xtr, ytr)
    best = search.best_estimator_
    test_acc = float(np.mean(best.predict(xte) == yte))
    info = {
        "best_params": {k: v for k, v in search.best_params_.items()},
        "cv_accuracy": float(search.best_score_),
        "test_accuracy": test_acc,
        "n_train": int(len(ytr)),
        "n_test": int(len(yte)),
        "n_dropped_degenerate": int((~ok).sum()),
        "test_size": test_size,
        "seed": seed,
        "n_support": int(best.named_steps["svc"].n_support_.sum()),
        "grid": {k: list(v) for k, v in (grid or DEFAULT_GRID).items()},
    }
    return best, info, (xte, yte)


def train_builtin(
    task: str, seed: int = 0, grid: dict[str, list[Any]] | None = None, n_jobs: int = 1
) -> tuple[GestureModel, tuple[np.ndarray, np.ndarray]]:
    """Fit the paper-sized model for ``task`` (``grip``/``screw``) on built-in synthetic data.

    Returns:
        The model and its held-out ``(features, labels)``.
    """
    task = TASK_MODEL.get(task, task)
    joints, labels, hands = synthetic_dataset(task, seed)
    feats = features_3d(joints, "openxr", hands)
    pipe, info, held = fit(
        feats, labels, test_size=PAPER_TEST_SIZE[task], seed=seed, grid=grid, n_jobs=n_jobs
    )
    info["data"] = (
        f"builtin synthetic (seed {seed}): shape families GESTURE_RANGES, random anatomy, "
        "no captured hands"
    )
    info["paper_accuracy"] = PAPER_ACCURACY[task]
    return GestureModel(pipe, TASK_CLASSES[task], "openxr", 3, task, info), held


def confusion(classes: tuple[str, ...] | list[str], truth: np.ndarray, pred: np.ndarray) -> str:
    """A printable confusion matrix (rows: truth, columns: prediction)."""
    classes = list(classes)
    idx = {c: i for i, c in enumerate(classes)}
    m = np.zeros((len(classes), len(classes)), dtype=int)
    for t, p in zip(truth, pred, strict=True):
        m[idx[str(t)], idx[str(p)]] += 1
    w = max(8, *(len(c) for c in classes))
    lines = ["truth \\ pred".ljust(w) + " " + " ".join(c[:w].rjust(w) for c in classes)]
    for c, row in zip(classes, m, strict=True):
        lines.append(c.ljust(w) + " " + " ".join(str(v).rjust(w) for v in row))
    return "\n".join(lines)
