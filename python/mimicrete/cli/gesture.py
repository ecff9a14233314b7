"""`mimicrete gesture train|eval`: fit / score the SVM gesture models (per-frame, or
``--temporal``: a window of frames, :mod:`mimicrete.gestures.temporal`)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mimicrete.cli import UsageError
from mimicrete.gestures import (
    PAPER_ACCURACY,
    PAPER_TEST_SIZE,
    TASK_CLASSES,
    TASK_MODEL,
    GestureCsv,
    GestureDataError,
    GestureModel,
    confusion,
    features_3d,
    featurize,
    fit,
    load_default,
    load_model,
    read_gesture_csv,
    sequence_dataset,
    synthetic_dataset,
    train_builtin,
)
from mimicrete.gestures.temporal import (
    DEFAULT_WINDOW,
    HELDOUT_SEEDS,
    TemporalGestureModel,
    fit_temporal,
    train_temporal_builtin,
)
from mimicrete.hands import LAYOUT_JOINTS
from mimicrete.tasks import TASKS


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
            choices=sorted(TASKS),
            default="grip",
            help="grip/suction/row: 3 classes; screw: 5 classes (default grip); a task names "
            "the gesture model its spec uses (about.gestures)",
        )
        p.add_argument(
            "--data",
            metavar="FILE.csv",
            help="labelled joints: label, then x,y[,z] per joint in layout order "
            "(default: built-in synthetic hands sized like the paper's)",
        )
        p.add_argument(
            "--layout",
            choices=sorted(LAYOUT_JOINTS),
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
                help="model file (default: ./gesture_<task>.joblib, or "
                "gesture_custom.joblib for --data)",
            )
            p.add_argument(
                "--quick", action="store_true", help="a 2×2 grid instead of the full C × gamma grid"
            )
            p.add_argument(
                "--temporal",
                action="store_true",
                help="a temporal model (features over a window of frames) trained on labelled "
                "sequences: --data needs a `sequence` column; without --data, the scripted "
                "demonstrator's episodes and gesture drills",
            )
            p.add_argument(
                "--window",
                type=int,
                default=None,
                help="--temporal: frames per window (default 9 = 0.1 s at 90 Hz)",
            )
            p.add_argument(
                "--sequences",
                type=int,
                default=12,
                help="--temporal without --data: seeds --seed … --seed+N-1 of built-in "
                "sequences (default 12: per seed one episode per demonstrator task + one drill)",
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
    except GestureDataError as e:
        raise UsageError(str(e)) from None


def _report(task: str, classes, truth, pred, n_test: int, what: str = "held-out") -> None:
    acc = float(np.mean(np.asarray(truth) == np.asarray(pred)))
    line = f"{what} accuracy: {100 * acc:.2f} % on {n_test} samples"
    if task in PAPER_ACCURACY:
        n_paper = {"grip": 165, "screw": 2078}[task]
        line += f"   (paper Table 1: {100 * PAPER_ACCURACY[task]:.2f} % on {n_paper})"
    print(line)
    print(confusion(classes, truth, pred))


def _main_train_temporal(args: argparse.Namespace) -> int:
    task = TASK_MODEL[args.task]
    grid = {"svc__C": [1.0, 10.0], "svc__gamma": [0.003]} if args.quick else None
    window = args.window or DEFAULT_WINDOW
    if args.data:
        data = _load_csv_args(args)
        seqs = data.sequences()
        model, (xte, yte) = fit_temporal(
            seqs,
            "custom",
            window=window,
            test_size=args.test_size or 0.2,
            seed=args.seed,
            grid=grid,
        )
        model.info["data"] = str(args.data)
        out = Path(args.out or "gesture_custom_temporal.joblib")
    else:
        seeds = range(args.seed, args.seed + args.sequences)
        model, (xte, yte) = train_temporal_builtin(task, seeds, window=window, grid=grid)
        out = Path(args.out or f"gesture_{task}_temporal.joblib")
    model.save(out)
    i = model.info
    print(
        f"saved {out} (+ .json): temporal, window {model.window} frames, best "
        f"{i['best_params']}, 5-fold CV accuracy {100 * i['cv_accuracy']:.2f} % (folds and "
        f"held-out part are whole sequences), {i['n_support']} support vectors"
    )
    _report(
        "custom", model.classes, yte, model.pipeline.predict(xte), len(yte), "held-out sequences"
    )
    return 0


def _main_train(args: argparse.Namespace) -> int:
    if args.temporal:
        return _main_train_temporal(args)
    task = TASK_MODEL[args.task]
    grid = {"svc__C": [10.0, 100.0], "svc__gamma": ["scale", 0.03]} if args.quick else None
    if args.data:
        data = _load_csv_args(args)
        hands = data.hands()
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
        out = Path(args.out or f"gesture_{task}.joblib")  # never into the installed package
    model.save(out)
    i = model.info
    print(
        f"saved {out} (+ .json): best {i['best_params']}, 5-fold CV accuracy "
        f"{100 * i['cv_accuracy']:.2f} %, {i['n_support']} support vectors"
    )
    _report(model.task, model.classes, yte, model.pipeline.predict(xte), len(yte))
    return 0


def _eval_temporal(args: argparse.Namespace, model: TemporalGestureModel) -> int:
    if args.data:
        seqs = _load_csv_args(args, model.info.get("label_names")).sequences()
        what = f"{Path(args.data).name} (every sequence, no split)"
    else:
        if model.task not in TASK_CLASSES:
            raise UsageError("a custom model needs --data to be scored")
        seqs = sequence_dataset(model.task, HELDOUT_SEEDS)
        seeds = f"{HELDOUT_SEEDS.start}..{HELDOUT_SEEDS.stop - 1}"
        what = f"held-out built-in sequences (seeds {seeds})"
    truth, pred = [], []
    for s in seqs:
        p = model.predict_sequence(s.joints, s.handedness, s.layout, s.tracked)
        truth.append(np.asarray(s.labels)[s.tracked])
        pred.append(np.where(p == None, "<degenerate>", p)[s.tracked])  # noqa: E711
    truth_a, pred_a = np.concatenate(truth), np.concatenate(pred)
    classes = list(model.classes)
    extra = sorted(set(map(str, truth_a)) - set(classes))
    if "<degenerate>" in pred_a:
        extra.append("<degenerate>")
    _report(model.task, classes + extra, truth_a, pred_a, len(truth_a), what)
    return 0


def _main_eval(args: argparse.Namespace) -> int:
    task = TASK_MODEL[args.task]
    model = load_model(args.model) if args.model else load_default(task)
    if isinstance(model, TemporalGestureModel):
        return _eval_temporal(args, model)
    if args.data:
        data = _load_csv_args(args, model.info.get("label_names"))
        if data.dims != model.dims:
            raise UsageError(
                f"{args.data} holds {data.dims}-D {data.layout} joints, the model "
                f"expects {model.dims}-D {model.layout}"
            )
        feats = featurize(data.joints, data.layout, data.dims, data.hands())
        truth = data.labels
        what = f"{Path(args.data).name} (every row, no split)"
    else:
        if model.task not in TASK_CLASSES:
            raise UsageError("a custom model needs --data to be scored")
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
