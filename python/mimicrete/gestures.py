"""Gesture recognition from hand joints: features, SVM models, CSV data, stream smoothing.

Paper §3.2 / Table 1: an RBF support vector machine per task, tuned by 5-fold cross-validation.

* ``grip`` (gripping and suction): 3 classes ``closing`` (suction / gripper close), ``opening``
  (drop / gripper open), ``fixed`` (hold). Built-in data: 827 samples (290 / 274 / 263), 80/20
  split; the paper reports 98.19 % on its 165 test samples.
* ``screw``: 5 classes, the tuples (gripping gesture, screwing gesture) of the paper:
  ``closing_tightening``, ``closing_loosening``, ``closing_fixed``, ``opening_stopped``,
  ``fixed_stopped``. Built-in data: 6,925 samples (1475 / 1289 / 1494 / 1209 / 1458), 70/30
  split; the paper reports 99.28 % on 2,078 test samples.

Features. 3-D joints (any layout) are reduced to the 21 landmarks every layout has, expressed in
the hand's own frame (origin wrist, ``y`` = wrist → middle proximal, ``z`` = (index proximal →
middle proximal) × ``y``, ``x = y × z``; left hands mirrored ``z → −z``) and divided by the
wrist → middle-proximal length: the same gesture gives the same features wherever the hand is,
however it is turned, whatever its size. 2-D image landmarks (``x, y`` only, e.g. MediaPipe
``keypoint.csv`` rows) are made relative to the wrist, rotated so that wrist → middle MCP points
along ``+y`` and divided by that length.

The built-in data come from the parametric hand (:mod:`mimicrete.handmodel`): per-class finger
shapes jittered per sample, a share of in-between shapes (blends toward another class, as hands
caught mid-change), hand sizes 0.8-1.2, any wrist orientation, left and right hands, and
tracking noise that grows for fingertips hidden in a curled hand.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import platform
import sys
import warnings
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import handmodel as hm

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
#: Which finger shape (:data:`mimicrete.handmodel.GESTURE_SHAPES`) each class is made with.
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
#: Paper §3.2: samples per class and the held-out share.
PAPER_COUNTS: dict[str, tuple[int, ...]] = {
    "grip": (290, 274, 263),
    "screw": (1475, 1289, 1494, 1209, 1458),
}
PAPER_TEST_SIZE: dict[str, float] = {"grip": 0.2, "screw": 0.3}
#: Paper Table 1: held-out accuracy.
PAPER_ACCURACY: dict[str, float] = {"grip": 0.9819, "screw": 0.9928}
#: Task names the rest of the package uses → gesture model.
TASK_MODEL: dict[str, str] = {"suction": "grip", "grip": "grip", "screw": "screw"}

DEFAULT_GRID: dict[str, list[Any]] = {
    "svc__C": [0.3, 1.0, 10.0, 100.0],
    "svc__gamma": ["scale", 0.001, 0.003, 0.01, 0.03],
}
DATA_DIR = Path(__file__).resolve().parent / "data"


class GestureDataError(ValueError):
    """A gesture CSV is malformed; the message starts with ``file:line:``."""


# ----------------------------------------------------------------------------------------------
# Features
# ----------------------------------------------------------------------------------------------


def features_3d(
    joints: np.ndarray, layout: str = "openxr", handedness: Any = "right"
) -> np.ndarray:
    """Pose-, position- and size-invariant features of 3-D hand joints.

    Args:
        joints: ``(N, 3)`` or ``(B, N, 3)`` joint positions in ``layout`` order.
        layout: the joint order (``openxr``, ``webxr``, ``meta_ovr``, ``mediapipe``).
        handedness: ``"left"``/``"right"`` or a ``(B,)`` array of them.

    Returns:
        ``(60,)`` or ``(B, 60)``: the 20 non-wrist canonical landmarks in the hand frame, divided
        by the wrist → middle-proximal length. Degenerate hands (collinear frame joints) give NaN.
    """
    j = np.asarray(joints, dtype=np.float64)
    single = j.ndim == 2
    if single and j.shape[-1] == 3:
        return _features_3d_one(hm.canonical21(j, layout), handedness == "left")
    if single:
        j = j[None]
    c = hm.canonical21(j, layout)
    if c.shape[-1] != 3:
        raise ValueError(f"features_3d needs x,y,z coordinates, got {c.shape[-1]} per joint")
    wrist = c[:, 0]
    yv = c[:, 9] - wrist
    xv = c[:, 9] - c[:, 5]
    length = np.linalg.norm(yv, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        y = yv / length
        zv = np.cross(xv, y)
        z = zv / np.linalg.norm(zv, axis=-1, keepdims=True)
        x = np.cross(y, z)
        rot = np.stack([x, y, z], axis=-1)  # (B, 3, 3), columns = axes
        rel = (c[:, 1:] - wrist[:, None]) / length[:, None]
    local = np.einsum("bnk,bkj->bnj", rel, rot)
    left = np.broadcast_to(np.asarray(handedness) == "left", (j.shape[0],))
    local[left, :, 2] *= -1.0
    out = local.reshape(j.shape[0], -1)
    return out[0] if single else out


def _features_3d_one(c: np.ndarray, left: bool) -> np.ndarray:
    """:func:`features_3d` of one hand's canonical landmarks ``(21, 3)`` (the per-frame path:
    scalar cross products, no batch machinery)."""
    w = c[0]
    yx, yy, yz = c[9] - w
    length = math.sqrt(yx * yx + yy * yy + yz * yz)
    if not length > 1e-12:
        return np.full(60, np.nan)
    yx, yy, yz = yx / length, yy / length, yz / length
    ax, ay, az = c[9] - c[5]
    zx, zy, zz = ay * yz - az * yy, az * yx - ax * yz, ax * yy - ay * yx
    nz = math.sqrt(zx * zx + zy * zy + zz * zz)
    if not nz > 1e-12:
        return np.full(60, np.nan)
    zx, zy, zz = zx / nz, zy / nz, zz / nz
    rot = np.array(
        [[yy * zz - yz * zy, yx, zx], [yz * zx - yx * zz, yy, zy], [yx * zy - yy * zx, yz, zz]]
    )
    local = ((c[1:] - w) / length) @ rot
    if left:
        local[:, 2] *= -1.0
    return local.ravel()


def features_2d(points: np.ndarray, layout: str = "mediapipe") -> np.ndarray:
    """Rotation-, position- and scale-invariant features of 2-D image landmarks.

    Args:
        points: ``(N, 2)`` or ``(B, N, 2)`` in ``layout`` order (already wrist-relative or not,
            normalised or in pixels: all the same after this).

    Returns:
        ``(40,)`` or ``(B, 40)``: the 20 non-wrist canonical landmarks relative to the wrist,
        rotated so wrist → middle MCP is ``+y``, divided by that length.
    """
    p = np.asarray(points, dtype=np.float64)
    single = p.ndim == 2
    if single:
        p = p[None]
    c = hm.canonical21(p, layout)
    if c.shape[-1] != 2:
        raise ValueError(f"features_2d needs x,y coordinates, got {c.shape[-1]} per joint")
    rel = c[:, 1:] - c[:, :1]
    v = rel[:, 8]  # middle MCP (canonical index 9, minus the wrist)
    length = np.linalg.norm(v, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos, sin = v[:, 1] / length, v[:, 0] / length  # rotate v onto +y
        xr = cos[:, None] * rel[..., 0] - sin[:, None] * rel[..., 1]
        yr = sin[:, None] * rel[..., 0] + cos[:, None] * rel[..., 1]
        out = np.stack([xr, yr], axis=-1) / length[:, None, None]
    out = out.reshape(p.shape[0], -1)
    return out[0] if single else out


def featurize(joints: np.ndarray, layout: str, dims: int, handedness: Any = "right") -> np.ndarray:
    """Dispatch to :func:`features_3d` (``dims == 3``) or :func:`features_2d` (``dims == 2``)."""
    if dims == 3:
        return features_3d(joints, layout, handedness)
    if dims == 2:
        return features_2d(joints, layout)
    raise ValueError(f"dims must be 2 or 3, got {dims}")


# ----------------------------------------------------------------------------------------------
# Built-in data
# ----------------------------------------------------------------------------------------------


def sample_gesture_hand(
    label: str,
    rng: np.random.Generator,
    *,
    ambiguity: float = 0.15,
    classes: tuple[str, ...] | None = None,
) -> tuple[np.ndarray, str]:
    """One noisy OpenXR hand ``(26, 3)`` making gesture class ``label``, and its handedness.

    With probability ``ambiguity`` the shape is blended part-way (10-50 %) toward another
    class of ``classes``: a hand caught forming or leaving the gesture, still labelled ``label``.
    """
    shape = hm.jitter_shape(hm.GESTURE_SHAPES[CLASS_SHAPE[label]], rng, sd=0.07)
    if classes and rng.random() < ambiguity:
        others = [c for c in classes if CLASS_SHAPE[c] != CLASS_SHAPE[label]]
        other = hm.GESTURE_SHAPES[CLASS_SHAPE[others[rng.integers(len(others))]]]
        shape = shape.lerp(other, float(rng.uniform(0.1, 0.5)))
    handed = "left" if rng.random() < 0.2 else "right"
    joints = hm.hand_joints(
        shape,
        hm.random_rotation(rng),
        rng.uniform(-0.5, 0.5, size=3) + np.array([0.0, 1.2, -0.4]),
        scale=float(rng.uniform(0.8, 1.2)),
        handedness=handed,
    )
    sigma = float(rng.uniform(0.001, 0.005))
    return hm.tracking_noise(joints, rng, sigma=sigma, occluded_sigma=0.008), handed


def synthetic_dataset(
    task: str, seed: int = 0, counts: tuple[int, ...] | None = None, layout: str = "openxr"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Built-in labelled hands sized like the paper's.

    Returns:
        ``(joints (n, N, 3), labels (n,) str, handedness (n,) str)`` in ``layout`` order, shuffled.
    """
    classes = TASK_CLASSES[task]
    counts = counts or PAPER_COUNTS[task]
    rng = np.random.default_rng([seed, 0x6E57])
    joints, labels, hands = [], [], []
    for label, n in zip(classes, counts, strict=True):
        for _ in range(n):
            j, h = sample_gesture_hand(label, rng, classes=classes)
            joints.append(j)
            labels.append(label)
            hands.append(h)
    order = rng.permutation(len(labels))
    j = hm.to_layout(np.array(joints)[order], layout)
    return j, np.array(labels)[order], np.array(hands)[order]


# ----------------------------------------------------------------------------------------------
# CSV
# ----------------------------------------------------------------------------------------------

#: values per row (after the label) → (layout, dims); every count is distinct.
_WIDTHS: dict[int, tuple[str, int]] = {
    n * d: (layout, d) for layout, n in hm.LAYOUT_JOINTS.items() for d in (2, 3)
}


@dataclass
class GestureCsv:
    """A labelled gesture CSV: ``labels (n,)``, ``joints (n, N, dims)``, its layout and dims."""

    labels: np.ndarray
    joints: np.ndarray
    layout: str
    dims: int
    path: str = ""


def read_gesture_csv(
    path: str | Path, layout: str | None = None, label_names: list[str] | None = None
) -> GestureCsv:
    """Read rows ``label, x0, y0[, z0], x1, ...`` (no header; a UTF-8 BOM is allowed).

    Args:
        path: the CSV file.
        layout: joint order; inferred from the row width when ``None`` (42 values = MediaPipe
            2-D, as the public ``keypoint.csv`` exports, 63 = MediaPipe 3-D, 78 = OpenXR 3-D, …).
        label_names: names for integer labels ``0, 1, …`` (e.g. ``["open", "close", "pointer"]``).

    Raises:
        GestureDataError: ``file:line: reason`` for the first bad row.
    """
    path = str(path)
    if layout is not None:
        layout = hm.check_layout(layout)
    labels: list[str] = []
    rows: list[list[float]] = []
    width: int | None = None
    with open(path, encoding="utf-8-sig", newline="") as f:
        for lineno, row in enumerate(csv.reader(f), start=1):
            if not row or all(not c.strip() for c in row):
                continue
            label = row[0].strip()
            if not label:
                raise GestureDataError(f"{path}:{lineno}: empty label in column 1")
            vals = row[1:]
            if width is None:
                width = len(vals)
                if layout is None:
                    if width not in _WIDTHS:
                        raise GestureDataError(
                            f"{path}:{lineno}: {width} coordinates after the label fit no layout "
                            f"(expected one of {sorted(_WIDTHS)}: joints × 2 or × 3)"
                        )
                    layout = _WIDTHS[width][0]
                n = hm.LAYOUT_JOINTS[layout]
                if width not in (2 * n, 3 * n):
                    raise GestureDataError(
                        f"{path}:{lineno}: {width} coordinates after the label, but layout "
                        f"{layout} needs {2 * n} (x,y) or {3 * n} (x,y,z)"
                    )
            elif len(vals) != width:
                raise GestureDataError(
                    f"{path}:{lineno}: {len(vals)} coordinates after the label, earlier rows "
                    f"have {width}"
                )
            nums = []
            for col, v in enumerate(vals, start=2):
                try:
                    x = float(v)
                except ValueError:
                    raise GestureDataError(
                        f"{path}:{lineno}: column {col}: not a number: {v.strip()!r}"
                    ) from None
                if not np.isfinite(x):
                    raise GestureDataError(f"{path}:{lineno}: column {col}: not finite: {v!r}")
                nums.append(x)
            if label_names is not None:
                try:
                    label = label_names[int(label)]
                except (ValueError, IndexError):
                    raise GestureDataError(
                        f"{path}:{lineno}: label {label!r} is not an index into "
                        f"{len(label_names)} label names"
                    ) from None
            labels.append(label)
            rows.append(nums)
    if not rows or layout is None or width is None:
        raise GestureDataError(f"{path}:1: no data rows")
    n = hm.LAYOUT_JOINTS[layout]
    dims = width // n
    return GestureCsv(
        np.array(labels), np.array(rows).reshape(len(rows), n, dims), layout, dims, path
    )


def write_gesture_csv(path: str | Path, labels: np.ndarray, joints: np.ndarray) -> None:
    """Write rows ``label, coords…`` (the format :func:`read_gesture_csv` reads)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        for label, j in zip(labels, joints, strict=True):
            w.writerow([label, *(f"{v:.6g}" for v in np.asarray(j).ravel())])


# ----------------------------------------------------------------------------------------------
# Model
# ----------------------------------------------------------------------------------------------


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
        if self._fast is None:
            self._fast = FastRbfSvc.from_pipeline(self.pipeline) or False
        if self._fast:
            return self._fast.predict_one(f)
        return str(self.pipeline.predict(f[None])[0])

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
        """Write ``path`` (joblib) and ``path.json`` (versions, feature spec, training facts)."""
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
            },
            path,
            compress=3,
        )
        sidecar = {
            "format": "mimicrete.gesture_model",
            "version": 1,
            "versions": _versions(),
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
        x = (np.asarray(features, dtype=np.float64) - self.mean) / self.scale
        d2 = self.sv_sq - 2.0 * (self.sv @ x) + x @ x
        k = np.exp(-self.gamma * np.maximum(d2, 0.0))
        # part[r, c]: row r of the dual coefficients against class c's support vectors
        part = np.add.reduceat(self.dual * k, self.starts, axis=1)
        dec = part[self.pj - 1, self.pi] + part[self.pi, self.pj] + self.intercept
        winners = np.where(dec > 0, self.pi, self.pj)
        return np.bincount(winners, minlength=len(self.classes))

    def predict_one(self, features: np.ndarray) -> str:
        """The class of one feature vector."""
        return self.classes[int(np.argmax(self.votes(features)))]


def load_model(path: str | Path) -> GestureModel:
    """Load a model written by :meth:`GestureModel.save`; warns when the sklearn or numpy version
    differs from the one it was fitted with (pickled sklearn models may then misbehave)."""
    import joblib

    path = Path(path)
    side = Path(str(path) + ".json")
    info: dict[str, Any] = {}
    if side.exists():
        meta = json.loads(side.read_text())
        info = meta.get("info", {})
        now = _versions()
        for key in ("sklearn", "numpy"):
            then = meta.get("versions", {}).get(key)
            if then != now[key]:
                warnings.warn(
                    f"{path}: fitted with {key} {then}, running {now[key]}; retrain with "
                    f"`mimicrete gesture train` if predictions look wrong",
                    RuntimeWarning,
                    stacklevel=2,
                )
    else:
        warnings.warn(
            f"{path}: no sidecar {side.name}; versions unknown", RuntimeWarning, stacklevel=2
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sklearn's own InconsistentVersionWarning: ours is above
        d = joblib.load(path)
    return GestureModel(d["pipeline"], tuple(d["classes"]), d["layout"], d["dims"], d["task"], info)


def default_model_path(task: str) -> Path:
    """Where the shipped model for ``task`` (``grip``/``suction``/``screw``) lives."""
    return DATA_DIR / f"gesture_{TASK_MODEL.get(task, task)}.joblib"


def load_default(task: str) -> GestureModel:
    """The shipped model for a task (``suction`` and ``grip`` share the 3-class model)."""
    path = default_model_path(task)
    if not path.exists():
        raise FileNotFoundError(
            f"{path} missing: run `mimicrete gesture train --task {TASK_MODEL.get(task, task)}`"
        )
    return load_model(path)


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
    info["data"] = f"builtin synthetic (seed {seed})"
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


# ----------------------------------------------------------------------------------------------
# Streaming
# ----------------------------------------------------------------------------------------------


class GestureSmoother:
    """Hysteresis over a stream of per-frame gestures.

    The output only switches to a new gesture once it has won at least ``k`` of the last ``n``
    classified frames; until then the previous output holds. Untracked frames (``None``) are
    skipped (they neither vote nor clear the history). With ``k > n // 2`` a single misread frame,
    or any ``n - k`` misread frames in a window, can never change the output.
    """

    def __init__(self, n: int = 7, k: int = 5, initial: str | None = None) -> None:
        if not 0 < k <= n:
            raise ValueError(f"need 0 < k <= n, got k={k}, n={n}")
        self.n, self.k = n, k
        self.initial = initial
        self.state: str | None = initial
        self._window: deque[str] = deque(maxlen=n)

    def reset(self) -> None:
        """Forget the history and go back to the initial output."""
        self.state = self.initial
        self._window.clear()

    def update(self, label: str | None) -> str | None:
        """Feed one frame's classification (``None`` = no usable hand); returns the output."""
        if label is None:
            return self.state
        self._window.append(label)
        if label != self.state:
            if sum(1 for x in self._window if x == label) >= self.k:
                self.state = label
        return self.state


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------


def configure(parser: argparse.ArgumentParser) -> None:
    """Flags of ``mimicrete gesture train|eval``."""
    sub = parser.add_subparsers(dest="gesture_cmd", metavar="{train,eval}", required=True)
    for name, help_text in (
        ("train", "fit an SVM (RBF, 5-fold CV grid search) and save it with a JSON sidecar"),
        ("eval", "held-out accuracy beside the paper's and a confusion matrix"),
    ):
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument(
            "--task",
            choices=["grip", "suction", "screw"],
            default="grip",
            help="grip/suction: 3 classes; screw: 5 classes (default grip)",
        )
        p.add_argument(
            "--data",
            metavar="FILE.csv",
            help="labelled joints: label, then x,y[,z] per joint in layout order "
            "(default: built-in synthetic hands sized like the paper's)",
        )
        p.add_argument(
            "--layout",
            choices=sorted(hm.LAYOUT_JOINTS),
            help="joint order of --data (inferred from the row width when omitted)",
        )
        p.add_argument(
            "--label-names", metavar="A,B,...", help="names of integer labels 0,1,... in --data"
        )
        p.add_argument("--seed", type=int, default=0, help="data / split / CV seed (default 0)")
        p.add_argument(
            "--test-size",
            type=float,
            default=None,
            help="held-out share (default: the paper's, 0.2 grip / 0.3 screw)",
        )
        if name == "train":
            p.add_argument(
                "--out",
                metavar="PATH",
                help="model file (default: the shipped model path for the task, or "
                "gesture_custom.joblib for --data)",
            )
            p.add_argument(
                "--quick", action="store_true", help="a 2×2 grid instead of the full C × gamma grid"
            )
        else:
            p.add_argument(
                "--model",
                metavar="PATH",
                help="model to score (default: the shipped one for --task)",
            )


def _load_csv_args(args: argparse.Namespace, default_names: list[str] | None = None) -> GestureCsv:
    names = args.label_names.split(",") if args.label_names else default_names
    return read_gesture_csv(args.data, args.layout, names)


def main(args: argparse.Namespace) -> int:
    """Run ``mimicrete gesture train|eval``; returns the exit code."""
    try:
        if args.gesture_cmd == "train":
            return _main_train(args)
        return _main_eval(args)
    except (GestureDataError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2


def _report(task: str, classes, truth, pred, n_test: int, what: str = "held-out") -> None:
    acc = float(np.mean(np.asarray(truth) == np.asarray(pred)))
    line = f"{what} accuracy: {100 * acc:.2f} % on {n_test} samples"
    if task in PAPER_ACCURACY:
        n_paper = {"grip": 165, "screw": 2078}[task]
        line += f"   (paper Table 1: {100 * PAPER_ACCURACY[task]:.2f} % on {n_paper})"
    print(line)
    print(confusion(classes, truth, pred))


def _main_train(args: argparse.Namespace) -> int:
    task = TASK_MODEL[args.task]
    grid = {"svc__C": [10.0, 100.0], "svc__gamma": ["scale", 0.03]} if args.quick else None
    if args.data:
        data = _load_csv_args(args)
        hands = np.full(len(data.labels), "right")
        feats = featurize(data.joints, data.layout, data.dims, hands)
        pipe, info, (xte, yte) = fit(
            feats, data.labels, test_size=args.test_size or 0.2, seed=args.seed, grid=grid
        )
        info["data"] = str(args.data)
        if args.label_names:
            info["label_names"] = args.label_names.split(",")
        classes = tuple(sorted(set(data.labels.tolist())))
        model = GestureModel(pipe, classes, data.layout, data.dims, "custom", info)
        out = Path(args.out or "gesture_custom.joblib")
    else:
        model, (xte, yte) = train_builtin(task, args.seed, grid)
        out = Path(args.out) if args.out else default_model_path(task)
    model.save(out)
    i = model.info
    print(
        f"saved {out} (+ .json): best {i['best_params']}, 5-fold CV accuracy "
        f"{100 * i['cv_accuracy']:.2f} %, {i['n_support']} support vectors"
    )
    _report(model.task, model.classes, yte, model.pipeline.predict(xte), len(yte))
    return 0


def _main_eval(args: argparse.Namespace) -> int:
    task = TASK_MODEL[args.task]
    model = load_model(args.model) if args.model else load_default(task)
    if args.data:
        data = _load_csv_args(args, model.info.get("label_names"))
        if data.dims != model.dims:
            print(
                f"error: {args.data} holds {data.dims}-D {data.layout} joints, the model "
                f"expects {model.dims}-D {model.layout}",
                file=sys.stderr,
            )
            return 2
        feats = featurize(data.joints, data.layout, data.dims, "right")
        truth = data.labels
        what = f"{Path(args.data).name} (every row, no split)"
    else:
        if model.task not in TASK_CLASSES:
            print("error: a custom model needs --data to be scored", file=sys.stderr)
            return 2
        seed = int(model.info.get("seed", args.seed))
        joints, labels, hands = synthetic_dataset(model.task, seed)
        feats_all = features_3d(joints, "openxr", hands)
        from sklearn.model_selection import train_test_split

        ok = np.all(np.isfinite(feats_all), axis=1)
        _, feats, _, truth = train_test_split(
            feats_all[ok],
            labels[ok],
            test_size=PAPER_TEST_SIZE[model.task],
            random_state=seed,
            stratify=labels[ok],
        )
        what = f"held-out (built-in synthetic data, seed {seed}, the split the model never saw)"
    ok = np.all(np.isfinite(feats), axis=1)
    pred = np.full(len(truth), "<degenerate>", dtype=object)
    pred[ok] = model.pipeline.predict(feats[ok])
    classes = list(model.classes)
    extra = sorted(set(map(str, truth)) - set(classes))
    if not ok.all():
        extra.append("<degenerate>")
    _report(model.task, classes + extra, truth, pred, len(truth), what)
    return 0


__all__ = [
    "CLASS_SHAPE",
    "GestureCsv",
    "GestureDataError",
    "GestureModel",
    "GestureSmoother",
    "PAPER_ACCURACY",
    "PAPER_COUNTS",
    "TASK_CLASSES",
    "configure",
    "confusion",
    "default_model_path",
    "features_2d",
    "features_3d",
    "featurize",
    "fit",
    "load_default",
    "load_model",
    "main",
    "read_gesture_csv",
    "synthetic_dataset",
    "train_builtin",
    "write_gesture_csv",
]
