"""Gesture recognition from hand joints (paper §3.2, Table 1): features, labelled data, the SVM
models, fitting with 5-fold CV, and the smoother that turns per-frame classes into commands.
An RBF support vector machine per task, tuned by 5-fold cross-validation:

* ``grip`` (gripping and suction): 3 classes ``closing`` (suction / gripper close: a pinch),
  ``opening`` (drop / gripper open: an open hand), ``fixed`` (hold: pointing). Built-in data:
  827 samples (290 / 274 / 263), 80/20 split; the paper reports 98.19 % on its 165 test
  samples.
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

Temporal model (:mod:`.temporal`, beyond the paper): the per-frame features of a short window
of frames (median and change) into the same SVM, trained on labelled sequences
(:mod:`.sequences`: the scripted demonstrator's episodes and gesture drills); a model file's
``kind`` (``per-frame``/``temporal``) says which it is, ``load_model`` returns the right class,
and :data:`DEFAULT_KIND` picks the shipped default per task. Labelled CSVs may carry a
``sequence`` column (:mod:`.data`). Recording samples from a live hand: :mod:`.recorder`.

The built-in data come from the parametric hand (:mod:`mimicrete.hands.model`): each class's
shapes drawn from wide ranges (:data:`~mimicrete.hands.model.GESTURE_RANGES`: any pinch, any
open hand, any point; :data:`CLASS_FAMILIES`), a share of in-between shapes (blends toward
another class, as hands caught mid-change), random proportions, hand sizes 0.8-1.2, any wrist
orientation, left and right hands, and tracking noise that grows for fingertips hidden in a
curled hand. Default gestures: pinch = ``closing`` (suction on), open hand = ``opening``
(drop), point = ``fixed`` (hold).

The shipped models (``models/``, remade by ``python -m mimicrete.gestures.shipped``,
:mod:`.shipped`) are trained on those synthetic hands only and tested on hands captured on a
real headset (:mod:`.captured`: IWER's Quest-3 poses, moved and turned; ``models/README.md``).
"""

from __future__ import annotations

from .classes import (
    CLASS_FAMILIES,
    CLASS_SHAPE,
    DEFAULT_KIND,
    MODELS_DIR,
    PAPER_ACCURACY,
    PAPER_COUNTS,
    PAPER_TEST_SIZE,
    TASK_CLASSES,
    TASK_MODEL,
    GestureDataError,
)
from .data import (
    GestureCsv,
    read_gesture_csv,
    sample_gesture_hand,
    synthetic_dataset,
    write_gesture_csv,
)
from .features import features_2d, features_3d, featurize
from .files import default_model_path, load_default, load_model
from .model import FastRbfSvc, GestureModel, confusion, fit, train_builtin
from .sequences import GestureSequence, demo_sequences, drill_sequence, sequence_dataset
from .smoother import GestureSmoother
from .temporal import TemporalGestureModel, fit_temporal, train_temporal_builtin

__all__ = [
    "CLASS_FAMILIES",
    "CLASS_SHAPE",
    "DEFAULT_KIND",
    "GestureSequence",
    "TemporalGestureModel",
    "demo_sequences",
    "drill_sequence",
    "fit_temporal",
    "sequence_dataset",
    "train_temporal_builtin",
    "MODELS_DIR",
    "PAPER_ACCURACY",
    "PAPER_COUNTS",
    "PAPER_TEST_SIZE",
    "TASK_CLASSES",
    "TASK_MODEL",
    "FastRbfSvc",
    "GestureCsv",
    "GestureDataError",
    "GestureModel",
    "GestureSmoother",
    "confusion",
    "default_model_path",
    "features_2d",
    "features_3d",
    "featurize",
    "fit",
    "load_default",
    "load_model",
    "read_gesture_csv",
    "sample_gesture_hand",
    "synthetic_dataset",
    "train_builtin",
    "write_gesture_csv",
]
