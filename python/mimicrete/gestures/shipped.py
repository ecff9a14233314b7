"""The shipped gesture models: how they are made and how they read captured hands.

``python -m mimicrete.gestures.shipped`` remakes ``models/gesture_grip.joblib`` and
``models/gesture_screw.joblib`` (+ their ``.json`` sidecars) — the one command for them, see
``models/README.md``. Each is the paper's per-frame RBF SVM (5-fold CV grid search, the paper's
class sizes and split) fitted on the built-in synthetic hands only
(:func:`~mimicrete.gestures.model.train_builtin`: shape families
:data:`~mimicrete.hands.model.GESTURE_RANGES`, random proportions, sizes, wrist poses, both
hands, tracking noise). No captured hand is used to fit anything.

They are then *tested* on hands we did not make (:mod:`.captured`): IWER's Quest-3-captured
pinch / relaxed / point poses, moved and turned, both hands, half of the frames with
tracking noise (3 classes), and the 5 screwing classes spliced from those captured fingers;
:func:`captured_accuracy` gives the per-frame accuracy, stored in each sidecar's
``info.captured`` and printed by ``make bench`` (:mod:`mimicrete.bench.gestures`).
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np

from . import captured as cap
from .classes import MODELS_DIR, TASK_MODEL
from .model import GestureModel, train_builtin

# named, not __name__: run as `python -m`, this module is __main__, outside the package's logger
log = logging.getLogger("mimicrete.gestures.shipped")

#: Frames per captured test set (the poses / spliced shapes in turn, both hands).
CAPTURED_FRAMES: dict[str, int] = {"grip": 600, "screw": 1000}


def captured_accuracy(model: GestureModel, task: str, seed: int = 0) -> dict[str, Any]:
    """Per-frame accuracy of ``model`` on the captured test set of ``task``
    (:func:`.captured.captured_set`, seed ``seed``): overall, per class, and the confusion as
    ``{truth: {prediction: frames}}``; raises :class:`.captured.CapturedDataMissing` without
    IWER's files."""
    task = TASK_MODEL.get(task, task)
    joints, labels, hands = cap.captured_set(task, n=CAPTURED_FRAMES[task], seed=seed)
    pred = np.array([model.predict_one(j, h, "webxr") for j, h in zip(joints, hands, strict=True)])
    per_class, conf = {}, {}
    for c in model.classes:
        sel = labels == c
        per_class[c] = float(np.mean(pred[sel] == c))
        got, n = np.unique(pred[sel].astype(str), return_counts=True)
        conf[c] = {str(g): int(k) for g, k in zip(got, n, strict=True)}
    return {
        "data": "IWER 2.5.0 Quest-captured poses (relaxed/pinch/point)"
        + (", spliced into the 5 screw shapes" if task == "screw" else "")
        + f", moved and turned, both hands, {CAPTURED_FRAMES[task]} frames, seed {seed}",
        "accuracy": float(np.mean(pred == labels)),
        "per_class": per_class,
        "confusion": conf,
    }


def remake(
    out_dir: str | Path = MODELS_DIR,
    seed: int = 0,
    grid: dict[str, list[Any]] | None = None,
    tasks: tuple[str, ...] = ("grip", "screw"),
) -> dict[str, GestureModel]:
    """Fit and save the shipped models of ``tasks`` into ``out_dir`` (their captured-hand
    accuracy in the sidecar when IWER's files are installed)."""
    out = {}
    for task in tasks:
        t0 = time.perf_counter()
        model, _ = train_builtin(task, seed, grid)
        try:
            model.info["captured"] = captured_accuracy(model, task)
        except cap.CapturedDataMissing as e:
            model.info["captured"] = {"missing": str(e)}
        model.save(Path(out_dir) / f"gesture_{task}.joblib")
        i = model.info
        got = i["captured"].get("accuracy")
        log.info(
            f"{task}: best {i['best_params']}, CV {100 * i['cv_accuracy']:.2f} %, held-out "
            f"synthetic {100 * i['test_accuracy']:.2f} %, captured "
            + (f"{100 * got:.2f} %" if got is not None else "(IWER missing)")
            + f" ({time.perf_counter() - t0:.0f} s)"
        )
        out[task] = model
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m mimicrete.gestures.shipped", description="remake the shipped models"
    )
    p.add_argument("--out", default=str(MODELS_DIR), help="directory (default: the package's)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--task", choices=["grip", "screw"], action="append", help="default both")
    args = p.parse_args(argv)
    from mimicrete.console import show_messages

    show_messages()
    remake(args.out, args.seed, tasks=tuple(args.task or ("grip", "screw")))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
