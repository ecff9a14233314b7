"""Labelled gesture data: the built-in synthetic hands (sized like the paper's) and the labelled
CSV format users record.

Gesture CSV (what ``mimicrete gesture train|eval --data`` read, :func:`read_gesture_csv`):

* **Plain** (no header; MediaPipe ``keypoint.csv`` exports are this): each row is
  ``label, x0, y0[, z0], x1, …`` — the class, then every joint's coordinates in layout order.
  The layout and 2-D/3-D follow from the number of coordinates (42 = MediaPipe 2-D, 63 =
  MediaPipe 3-D, 72 = Meta OVR 3-D, 75 = WebXR 3-D, 78 = OpenXR 3-D, …; ``--layout`` to say it).
* **With a header** (first row's first cell is ``label``): columns ``label`` first, then any of
  ``sequence`` (an id: rows with the same id are consecutive frames of one take, in time
  order — what a temporal model trains on), ``t`` (seconds), ``handedness``
  (``left``/``right``), in any order, then the coordinates as above (their header cells are
  free text, e.g. ``x0,y0,z0``). Rows without a ``sequence`` column are each their own sample.

Both read the same way otherwise; files written without sequences, times or handedness are the
plain form, byte for byte as before.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete.hands import layouts
from mimicrete.hands import model as hm

from .classes import CLASS_FAMILIES, PAPER_COUNTS, TASK_CLASSES, GestureDataError


def sample_gesture_hand(
    label: str,
    rng: np.random.Generator,
    *,
    ambiguity: float = 0.15,
    classes: tuple[str, ...] | None = None,
) -> tuple[np.ndarray, str]:
    """One noisy OpenXR hand ``(26, 3)`` making gesture class ``label``, and its handedness.

    The shape is drawn from the class's families (:data:`~.classes.CLASS_FAMILIES`, uniform in
    :data:`~mimicrete.hands.model.GESTURE_RANGES`) on a hand of random proportions
    (:func:`~mimicrete.hands.model.random_anatomy`) and size. With probability ``ambiguity``
    the shape is blended part-way (10-50 %) toward a shape of another class of ``classes``: a
    hand caught forming or leaving the gesture, still labelled ``label``.
    """
    fams = CLASS_FAMILIES[label]
    shape = hm.sample_shape(fams[rng.integers(len(fams))], rng)
    if classes and rng.random() < ambiguity:
        others = [c for c in classes if set(CLASS_FAMILIES[c]) != set(fams)]
        ofams = CLASS_FAMILIES[others[rng.integers(len(others))]]
        other = hm.sample_shape(ofams[rng.integers(len(ofams))], rng)
        shape = shape.lerp(other, float(rng.uniform(0.1, 0.5)))
    handed = "left" if rng.random() < 0.2 else "right"
    joints = hm.hand_joints(
        shape,
        hm.random_rotation(rng),
        rng.uniform(-0.5, 0.5, size=3) + np.array([0.0, 1.2, -0.4]),
        scale=float(rng.uniform(0.8, 1.2)),
        handedness=handed,
        anatomy=hm.random_anatomy(rng),
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


#: Header names of the optional columns between the label and the coordinates.
META_COLUMNS = ("sequence", "t", "handedness")


@dataclass
class GestureCsv:
    """A labelled gesture CSV: ``labels (n,)``, ``joints (n, N, dims)``, its layout and dims, and
    the optional columns (``sequence`` ids as str, ``t`` seconds, ``handedness``), None when
    absent."""

    labels: np.ndarray
    joints: np.ndarray
    layout: str
    dims: int
    path: str = ""
    sequence: np.ndarray | None = None
    t: np.ndarray | None = None
    handedness: np.ndarray | None = None

    def hands(self) -> np.ndarray:
        """Handedness per row (``right`` where the file does not say)."""
        if self.handedness is None:
            return np.full(len(self.labels), "right")
        return self.handedness

    def sequences(self, layout: str | None = None) -> list[Any]:
        """The rows as :class:`~mimicrete.gestures.sequences.GestureSequence` s, one per
        ``sequence`` id in order of first appearance (3-D only; needs the ``sequence`` column;
        all frames tracked, none marked as changing: the file does not say)."""
        from .sequences import GestureSequence

        if self.sequence is None:
            raise GestureDataError(f"{self.path}: no sequence column (header `label,sequence,…`)")
        if self.dims != 3:
            raise GestureDataError(f"{self.path}: sequences need 3-D joints")
        out = []
        hands = self.hands()
        for sid in dict.fromkeys(self.sequence.tolist()):
            idx = np.flatnonzero(self.sequence == sid)
            t = self.t[idx] if self.t is not None else np.arange(len(idx)) / 90.0
            out.append(
                GestureSequence(
                    t,
                    self.joints[idx],
                    self.labels[idx],
                    np.ones(len(idx), dtype=bool),
                    np.zeros(len(idx), dtype=bool),
                    str(hands[idx[0]]),
                    layout or self.layout,
                    f"{self.path} sequence {sid}",
                )
            )
        return out


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
    meta: dict[str, list[str]] = {}
    meta_cols: list[str] = []
    width: int | None = None
    header_seen = False
    with open(path, encoding="utf-8-sig", newline="") as f:
        for lineno, row in enumerate(csv.reader(f), start=1):
            if not row or all(not c.strip() for c in row):
                continue
            if not header_seen and not rows and row[0].strip().lower() == "label":
                header_seen = True
                for c in row[1:]:
                    name = c.strip().lower()
                    if name not in META_COLUMNS:
                        break
                    if name in meta_cols:
                        raise GestureDataError(f"{path}:{lineno}: column {name!r} twice")
                    meta_cols.append(name)
                meta = {c: [] for c in meta_cols}
                continue
            label = row[0].strip()
            if not label:
                raise GestureDataError(f"{path}:{lineno}: empty label in column 1")
            if len(row) < 1 + len(meta_cols):
                raise GestureDataError(f"{path}:{lineno}: fewer columns than the header")
            for k, c in enumerate(meta_cols):
                v = row[1 + k].strip()
                if c == "handedness" and v not in ("left", "right"):
                    raise GestureDataError(
                        f"{path}:{lineno}: column {2 + k}: handedness {v!r} is not left/right"
                    )
                if c == "t":
                    try:
                        float(v)
                    except ValueError:
                        raise GestureDataError(
                            f"{path}:{lineno}: column {2 + k}: not a number: {v!r}"
                        ) from None
                meta[c].append(v)
            skip = 1 + len(meta_cols)
            vals = row[skip:]
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
            for col, v in enumerate(vals, start=skip + 1):
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
        np.array(labels),
        np.array(rows).reshape(len(rows), n, dims),
        layout,
        dims,
        path,
        np.array(meta["sequence"]) if "sequence" in meta else None,
        np.array(meta["t"], dtype=np.float64) if "t" in meta else None,
        np.array(meta["handedness"]) if "handedness" in meta else None,
    )


def write_gesture_csv(
    path: str | Path,
    labels: np.ndarray,
    joints: np.ndarray,
    *,
    sequence: Any = None,
    t: Any = None,
    handedness: Any = None,
) -> None:
    """Write the format :func:`read_gesture_csv` reads: plain rows ``label, coords…`` or, when
    any of ``sequence`` / ``t`` / ``handedness`` (one value per row, or one handedness for all)
    is given, a header ``label,<those>,c0,c1,…`` and those columns after the label."""
    n = len(labels)
    meta: list[tuple[str, list[str]]] = []
    if sequence is not None:
        meta.append(("sequence", [str(v) for v in np.asarray(sequence).reshape(n)]))
    if t is not None:
        meta.append(("t", [f"{float(v):.6f}" for v in np.asarray(t).reshape(n)]))
    if handedness is not None:
        h = np.broadcast_to(np.asarray(handedness), (n,))
        meta.append(("handedness", [str(v) for v in h]))
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        if meta:
            width = int(np.asarray(joints[0]).size) if n else 0
            w.writerow(["label", *(name for name, _ in meta), *(f"c{i}" for i in range(width))])
        for i, (label, j) in enumerate(zip(labels, joints, strict=True)):
            coords = (f"{v:.6g}" for v in np.asarray(j).ravel())
            w.writerow([label, *(vals[i] for _, vals in meta), *coords])
