"""Hand shapes captured on a real headset, as test data for the gesture models.

IWER (Meta's WebXR emulator, npm ``iwer`` 2.5.0, pinned in ``web/package-lock.json``) ships three
hand poses captured on a Quest 3 (``lib/device/configs/hand/{relaxed,pinch,point}.js``): for each
of the 25 WebXR joints its 4×4 offset matrix (column-major, metres, relative to the hand's target
ray space) and radius. They are a *left* hand; IWER makes the right one by mirroring the matrices
(x → −x), and so does :func:`iwer_pose`. The files are read as text (they are plain ES modules
of numbers); nothing of IWER's code runs.

These shapes are what the shipped models are *tested* on (:mod:`mimicrete.bench.gestures`,
``tests/gestures``), never trained on: see :mod:`mimicrete.gestures.shipped`.

* :func:`grip_captured_set`: the 3-class test set. Each of IWER's poses, left and right, under
  random rigid motions over the workspace (moved ±0.5 m, turned any way) and, in a share of the
  frames, with Quest-like tracking noise; labels by :data:`IWER_GRIP_CLASS`.
* :func:`screw_captured_set`: the 5-class test set. The screwing tuples need shapes IWER does not
  ship, so they are *spliced* from its captured fingers: every finger (its metacarpal → tip chain
  with the joint rotations the headset measured) is taken from one captured pose and re-attached
  to the palm of another, as :data:`SCREW_SPLICES` says, so every joint-to-joint angle in a
  finger is a captured one.
* :func:`keypoint_check`: real webcam hands in 2-D (a public MediaPipe ``keypoint.csv``, not
  shipped): how well the synthetic hands, seen by a camera, stand for them.
"""

from __future__ import annotations

import os
import re
from functools import cache
from pathlib import Path

import numpy as np

from mimicrete._native import MimicreteError
from mimicrete.hands.layouts import WEBXR_JOINT_NAMES

#: IWER's pose files, by the pose id IWER gives them (``default`` is the relaxed hand).
IWER_POSE_FILES: dict[str, str] = {"default": "relaxed", "pinch": "pinch", "point": "point"}
#: The default hand shape of each suction / gripping class (pose id in IWER).
IWER_GRIP_CLASS: dict[str, str] = {"pinch": "closing", "default": "opening", "point": "fixed"}
#: WebXR joint ranges of each finger chain (metacarpal … tip; the thumb metacarpal … tip).
FINGER_JOINTS: dict[str, range] = {
    "thumb": range(1, 5),
    "index": range(5, 10),
    "middle": range(10, 15),
    "ring": range(15, 20),
    "little": range(20, 25),
}
#: The 5 screwing classes as captured fingers on a captured palm: ``(palm pose, {finger: pose})``
#: (fingers not named come from the palm pose). The gripping half of each tuple is the grip
#: class's shape (closing: pinch, opening: relaxed, fixed: point); the screwing half is told by
#: the other three fingers: curled (the point pose's curled fingers) for tightening, the little
#: finger alone straight (the relaxed pose's) for loosening.
SCREW_SPLICES: dict[str, tuple[str, dict[str, str]]] = {
    "closing_tightening": ("pinch", {"middle": "point", "ring": "point", "little": "point"}),
    "closing_loosening": ("pinch", {"middle": "point", "ring": "point", "little": "default"}),
    "closing_fixed": ("pinch", {}),
    "opening_stopped": ("default", {}),
    "fixed_stopped": ("point", {}),
}


class CapturedDataMissing(MimicreteError, FileNotFoundError):
    """IWER's pose files are not installed (``cd web && npm ci``)."""


def iwer_dir() -> Path:
    """The installed ``iwer`` package: ``$MIMICRETE_IWER_DIR``, else ``web/node_modules/iwer`` of
    this checkout."""
    env = os.environ.get("MIMICRETE_IWER_DIR")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "web" / "node_modules" / "iwer"


_NUM = r"-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?"
_JOINT = re.compile(
    r"'?([a-z-]+)'?\s*:\s*\{\s*offsetMatrix\s*:\s*\[([^\]]*)\]\s*,\s*radius\s*:\s*(" + _NUM + ")"
)


@cache
def _pose_matrices(pose: str, root: str) -> np.ndarray:
    name = IWER_POSE_FILES[pose]
    path = Path(root) / "lib" / "device" / "configs" / "hand" / f"{name}.js"
    if not path.is_file():
        raise CapturedDataMissing(f"{path}: IWER's captured hand poses are missing (npm ci)")
    found = {m[1]: m[2] for m in _JOINT.finditer(path.read_text())}
    out = np.zeros((25, 4, 4))
    for k, joint in enumerate(WEBXR_JOINT_NAMES):
        if joint not in found:
            raise CapturedDataMissing(f"{path}: no joint {joint!r}")
        vals = [float(v) for v in re.findall(_NUM, found[joint])]
        if len(vals) != 16:
            raise CapturedDataMissing(f"{path}: joint {joint!r} has {len(vals)} matrix values")
        out[k] = np.array(vals).reshape(4, 4).T  # column-major → row-major
    return out


_MIRROR = np.diag([-1.0, 1.0, 1.0, 1.0])


def iwer_matrices(pose: str, handedness: str = "left") -> np.ndarray:
    """The 25 joint matrices ``(25, 4, 4)`` (row-major, translation in the last column) of IWER
    pose ``pose`` (``default``/``pinch``/``point``), as IWER gives them for that hand (the right
    hand is the captured left one mirrored x → −x, as IWER's ``mirrorMatrixToRight`` does)."""
    m = _pose_matrices(pose, str(iwer_dir()))
    if handedness == "right":
        return _MIRROR @ m @ _MIRROR
    if handedness != "left":
        raise ValueError(f"handedness must be 'left' or 'right', got {handedness!r}")
    return m.copy()


def iwer_pose(pose: str, handedness: str = "left") -> np.ndarray:
    """Joint positions ``(25, 3)``, WebXR order, of IWER pose ``pose`` for ``handedness``."""
    return iwer_matrices(pose, handedness)[:, :3, 3]


def splice(palm: str, fingers: dict[str, str], handedness: str = "left") -> np.ndarray:
    """A hand ``(25, 3)`` made of captured parts: pose ``palm``'s wrist and palm, and each finger
    of ``fingers`` taken from another pose with its joint angles kept: the finger's joints are
    expressed in its own metacarpal frame (wrist frame for the thumb, whose metacarpal moves)
    in the pose they come from and placed on the same frame of ``palm``."""
    base = iwer_matrices(palm, handedness)
    out = base[:, :3, 3].copy()
    for finger, pose in fingers.items():
        src = iwer_matrices(pose, handedness)
        idx = list(FINGER_JOINTS[finger])
        anchor = 0 if finger == "thumb" else idx[0]
        to_local = np.linalg.inv(src[anchor])
        for k in idx:
            if k == anchor:
                continue
            local = to_local @ src[k][:, 3]
            out[k] = (base[anchor] @ local)[:3]
    return out


def _rigid(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    from mimicrete.hands.model import random_rotation

    return random_rotation(rng), rng.uniform(-0.5, 0.5, size=3) + np.array([0.0, 1.2, -0.4])


def quest_noise(joints: np.ndarray, rng: np.random.Generator, sigma: float = 0.002) -> np.ndarray:
    """Jitter of a hand-tracking frame: isotropic ``sigma`` on every joint (Quest's joint jitter
    is a few millimetres, our assumption), twice that on the fingertips."""
    j = np.asarray(joints, dtype=np.float64)
    scale = np.ones(len(j))
    scale[[4, 9, 14, 19, 24]] = 2.0
    return j + rng.normal(size=j.shape) * sigma * scale[:, None]


def _moved(
    shapes: list[tuple[str, np.ndarray, str]], n: int, seed: int, noisy: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng([seed, 0x1BE2])
    joints, labels, hands = [], [], []
    for k in range(n):
        label, local, hand = shapes[k % len(shapes)]
        rot, pos = _rigid(rng)
        j = local @ rot.T + pos
        if rng.random() < noisy:
            j = quest_noise(j, rng)
        joints.append(j)
        labels.append(label)
        hands.append(hand)
    return np.array(joints), np.array(labels), np.array(hands)


def grip_captured_set(
    n: int = 600, seed: int = 0, noisy: float = 0.5
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IWER's three captured poses as 3-class frames, moved and turned over the workspace.

    Returns:
        ``(joints (n, 25, 3) WebXR layout, labels (n,), handedness (n,))``: the poses in turn,
        each hand in turn, each frame under its own random rotation and position; a share
        ``noisy`` of them with :func:`quest_noise`.
    """
    shapes = [
        (cls, iwer_pose(pose, hand), hand)
        for pose, cls in IWER_GRIP_CLASS.items()
        for hand in ("left", "right")
    ]
    return _moved(shapes, n, seed, noisy)


def screw_captured_set(
    n: int = 1000, seed: int = 0, noisy: float = 0.5
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 5 screwing classes spliced from IWER's captured fingers (:data:`SCREW_SPLICES`),
    moved and turned as :func:`grip_captured_set`."""
    shapes = [
        (cls, splice(palm, fingers, hand), hand)
        for cls, (palm, fingers) in SCREW_SPLICES.items()
        for hand in ("left", "right")
    ]
    return _moved(shapes, n, seed, noisy)


def captured_set(task: str, **kw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`grip_captured_set` (``grip``/``suction``) or :func:`screw_captured_set`."""
    from .classes import TASK_MODEL

    task = TASK_MODEL.get(task, task)
    return grip_captured_set(**kw) if task == "grip" else screw_captured_set(**kw)


__all__ = [
    "FINGER_JOINTS",
    "IWER_GRIP_CLASS",
    "IWER_POSE_FILES",
    "SCREW_SPLICES",
    "CapturedDataMissing",
    "KEYPOINT_CLASSES",
    "captured_set",
    "grip_captured_set",
    "iwer_dir",
    "iwer_matrices",
    "iwer_pose",
    "keypoint_check",
    "quest_noise",
    "screw_captured_set",
    "splice",
]


# ----------------------------------------------------------------------------------------------
# Real webcam hands (2-D): a check of the synthetic hands, not of the 3-D models
# ----------------------------------------------------------------------------------------------

#: Labels of the public MediaPipe ``keypoint.csv`` of Kazuhito00/hand-gesture-recognition-using-
#: mediapipe (``model/keypoint_classifier/``; 4,450 webcam frames) → our 3-class names; its
#: ``Close`` (a fist) is no class of ours and is only reported.
KEYPOINT_CLASSES: dict[int, str | None] = {0: "opening", 1: None, 2: "fixed"}


def _webcam_view(rng: np.random.Generator) -> np.ndarray:
    """A hand held up before a webcam: fingers roughly up the image (±1 rad), tipped ±0.6 rad,
    palm, back or edge toward the camera."""
    from mimicrete.hands.model import rotation_matrix

    return (
        rotation_matrix([0, 0, 1], rng.uniform(-1.0, 1.0))
        @ rotation_matrix([1, 0, 0], rng.uniform(-0.6, 0.6))
        @ rotation_matrix([0, 1, 0], rng.uniform(-np.pi, np.pi))
    )


def keypoint_check(path: str | Path, per_class: int = 600, seed: int = 0) -> dict:
    """How well the synthetic hands stand for real ones, on 2-D webcam landmarks we did not make.

    A 2-D RBF SVM is fitted on the built-in synthetic 3-class hands
    (:func:`~mimicrete.gestures.data.sample_gesture_hand`) seen by a webcam (orthographic, image
    ``y`` down, half mirrored as a left hand or a selfie view) and scored on the rows of the
    public ``keypoint.csv`` at ``path`` (:data:`KEYPOINT_CLASSES`). The file is not shipped.

    Returns:
        ``{"synthetic_heldout", "per_class": {label: accuracy}, "open_pointer", "counts"}``.
    """
    from mimicrete.hands import layouts
    from mimicrete.hands.model import hand_frame

    from .data import sample_gesture_hand
    from .features import features_2d
    from .model import fit

    rng = np.random.default_rng([seed, 0x2D])
    classes = ("closing", "opening", "fixed")
    feats, labels = [], []
    for label in classes:
        for _ in range(per_class):
            j, hand = sample_gesture_hand(label, rng, classes=classes)
            rot, origin = hand_frame(j[1], j[7], j[12])
            local = (layouts.to_layout(j, "mediapipe") - origin) @ rot
            if hand == "left":
                local[:, 2] *= -1.0  # the right hand's shape
            pts = local @ _webcam_view(rng).T
            img = np.stack([pts[:, 0], -pts[:, 1]], axis=1)
            if rng.random() < 0.5:
                img[:, 0] *= -1.0
            feats.append(features_2d(img))
            labels.append(label)
    grid = {"svc__C": [1.0, 10.0], "svc__gamma": ["scale", 0.03]}
    pipe, info, _ = fit(np.array(feats), np.array(labels), test_size=0.2, seed=seed, grid=grid)
    rows = np.loadtxt(path, delimiter=",", encoding="utf-8-sig", ndmin=2)
    kp = rows[:, 0].astype(int)
    pred = pipe.predict(features_2d(rows[:, 1:].reshape(-1, 21, 2)))
    out: dict = {"synthetic_heldout": info["test_accuracy"], "per_class": {}, "counts": {}}
    ok = []
    for k, want in KEYPOINT_CLASSES.items():
        sel = kp == k
        got, n = np.unique(pred[sel], return_counts=True)
        out["counts"][k] = {str(g): int(c) for g, c in zip(got, n, strict=True)}
        if want is not None and sel.any():
            out["per_class"][want] = float(np.mean(pred[sel] == want))
            ok.append(pred[sel] == want)
    out["open_pointer"] = float(np.mean(np.concatenate(ok))) if ok else float("nan")
    return out
