"""Labelled gesture data: the built-in synthetic hands (sized like the paper's) and the labelled
CSV format users record."""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimicrete.hands import layouts
from mimicrete.hands import model as hm

from .classes import CLASS_SHAPE, PAPER_COUNTS, TASK_CLASSES, GestureDataError


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
    j = layouts.to_layout(np.array(joints)[order], layout)
    return j, np.array(labels)[order], np.array(hands)[order]


# ----------------------------------------------------------------------------------------------
# CSV
# ----------------------------------------------------------------------------------------------

#: values per row (after the label) → (layout, dims); every count is distinct.
_WIDTHS: dict[int, tuple[str, int]] = {
    n * d: (layout, d) for layout, n in layouts.LAYOUT_JOINTS.items() for d in (2, 3)
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
        layout = layouts.check_layout(layout)
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
                n = layouts.LAYOUT_JOINTS[layout]
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
    n = layouts.LAYOUT_JOINTS[layout]
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
