"""The shipped gesture models on captured hands, and the per-frame SVM against the temporal model
on held-out labelled sequences, per model task.

First, per-frame accuracy of the shipped models on hands we did not make
(:func:`mimicrete.gestures.shipped.captured_accuracy`): IWER's Quest-3-captured pinch / relaxed /
point poses, moved and turned, both hands, half with tracking jitter (3 classes, 600 frames), and
the 5 screwing shapes spliced from those captured fingers (1,000 frames). Measured: 100 % / 100 %
(the models shipped before: 62.5 % / 40 %). Needs ``web/node_modules`` (``make bench`` installs
it). With ``MIMICRETE_KEYPOINT_CSV=path/to/keypoint.csv`` (the public MediaPipe webcam set of
Kazuhito00/hand-gesture-recognition-using-mediapipe, not shipped) also
:func:`mimicrete.gestures.captured.keypoint_check`.

Then the comparison below.

Sequences (:mod:`mimicrete.gestures.sequences`): scripted-demonstrator episodes (suction + grip
for the 3-class model, screw for the 5-class one) and gesture drills (every class, every change),
seeds :data:`~mimicrete.gestures.temporal.HELDOUT_SEEDS`; the temporal model trains on
:data:`~mimicrete.gestures.temporal.TRAIN_SEEDS` (disjoint). Models compared:

* ``per-frame (shipped)``: the shipped SVM (paper-sized static synthetic hands);
* ``per-frame (seqs)``: the per-frame SVM fitted on the temporal model's training frames (a
  control: the sequences' data without the window);
* ``temporal W9``: :class:`~mimicrete.gestures.temporal.TemporalGestureModel`, 9 frames.

Each runs exactly as the session asks it (``reset()``, then ``predict_margin`` per tracked frame);
metrics (:mod:`mimicrete.gestures.metrics`) raw, after the session's smoother (7 frames, 5
votes: ``smoothed``) and after a lighter one (3 frames, 2 votes: ``light``); also the cost of one
``predict_margin`` call.

Measured (6 held-out seeds × (episodes + drills), 84 true changes per task; with the pinch,
open hand and point of issue 23): raw, the temporal model never flickers (0 vs 0.45 /s grip,
0.58 /s screw per-frame) and is right on 100 % of held frames (per-frame 99.7 %); after the
session's 7/5 smoother both have 0 flicker, latency 44 ms median / 56-67 ms p90 and accuracy
within 0.15 points; a 3/2 vote on the per-frame model also gives 0 flicker at 11 / 22-33 ms.
Its per-frame cost is 2-4× the per-frame model's. So the per-frame SVM stays the default for
both tasks (:data:`mimicrete.gestures.DEFAULT_KIND`).
"""

from __future__ import annotations

import os
import time
from typing import Any

from mimicrete import gestures as gest
from mimicrete.gestures import captured as cap
from mimicrete.gestures import metrics as mt
from mimicrete.gestures import sequences as sq
from mimicrete.gestures import shipped
from mimicrete.gestures import temporal as tp


def captured() -> None:
    """Print the shipped models' per-frame accuracy on the captured hands, per class."""
    for task in ("grip", "screw"):
        model = gest.load_default(task)
        res = shipped.captured_accuracy(model, task)
        per = ", ".join(f"{c} {100 * a:.1f}" for c, a in res["per_class"].items())
        acc = 100 * res["accuracy"]
        print(f"shipped {task:5s} on captured hands: {acc:6.2f} % per frame ({per})")
        wrong = {t: {p: n for p, n in row.items() if p != t} for t, row in res["confusion"].items()}
        wrong = {t: row for t, row in wrong.items() if row}
        if wrong:
            print(f"   misread: {wrong}")
        print(f"   data: {res['data']}")
    kp = os.environ.get("MIMICRETE_KEYPOINT_CSV")
    if kp:  # the public MediaPipe webcam set (not shipped): a 2-D check of the synthetic hands
        r = cap.keypoint_check(kp)
        per = ", ".join(f"{c} {100 * a:.1f} %" for c, a in r["per_class"].items())
        print(
            f"2-D SVM on synthetic hands seen by a webcam, on {kp}: {per} (synthetic held-out "
            f"{100 * r['synthetic_heldout']:.1f} %); its fists read as {r['counts'][1]}"
        )


def _cost_us(model: Any, seq: sq.GestureSequence, n: int = 400) -> float:
    model.reset()
    t0 = time.perf_counter()
    for k in range(min(n, len(seq))):
        model.predict_margin(seq.joints[k], seq.handedness, seq.layout)
    return (time.perf_counter() - t0) / min(n, len(seq)) * 1e6


def compare(task: str, *, train_seeds: Any = None, test_seeds: Any = None) -> list[dict[str, Any]]:
    """Rows ``{task, model, data, stage, accuracy, held_accuracy, flicker_per_s, latency…}``."""
    train = sq.sequence_dataset(task, train_seeds or tp.TRAIN_SEEDS)
    test = sq.sequence_dataset(task, test_seeds or tp.HELDOUT_SEEDS)
    models: dict[str, Any] = {
        "per-frame (shipped)": gest.load_default(task, "per-frame"),
        "per-frame (seqs)": tp.fit_per_frame_on_sequences(
            train, task, grid={"svc__C": [1.0, 10.0], "svc__gamma": ["scale", 0.01]}
        ),
        "temporal W9": tp.fit_temporal(train, task, window=9)[0],
    }
    rows = []
    for name, model in models.items():
        cost = _cost_us(model, test[0])
        for data in ("episodes", "drills", "all"):
            sel = [s for s in test if data == "all" or s.source.startswith(data[:-1])]
            res = mt.evaluate(model, sel, light=(3, 2))
            for stage in ("raw", "smoothed", "light"):
                rows.append(
                    {"task": task, "model": name, "data": data, "stage": stage, "us": cost}
                    | res[stage]
                )
    return rows


def table(rows: list[dict[str, Any]]) -> str:
    head = (
        f"{'task':5s} {'model':20s} {'data':8s} {'stage':8s} {'acc %':>6s} {'held %':>6s} "
        f"{'flick/s':>7s} {'lat p50':>7s} {'lat p90':>7s} {'miss':>6s} {'µs/fr':>6s}"
    )
    lines = [head]
    for r in rows:
        lines.append(
            f"{r['task']:5s} {r['model']:20s} {r['data']:8s} {r['stage']:8s} "
            f"{100 * r['accuracy']:6.2f} {100 * r['held_accuracy']:6.2f} "
            f"{r['flicker_per_s']:7.3f} {r['latency_ms_median']:5.0f}ms "
            f"{r['latency_ms_p90']:5.0f}ms "
            f"{r['missed']:>2d}/{r['changes']:<3d} {r['us']:6.0f}"
        )
    return "\n".join(lines)


def run() -> None:
    """Print the captured-hand accuracy, then the comparison for both model tasks (grip
    3-class, screw 5-class)."""
    captured()
    for task in ("grip", "screw"):
        t0 = time.perf_counter()
        rows = compare(task)
        print(table(rows))
        print(f"   ({task}: {time.perf_counter() - t0:.0f} s)", flush=True)
    print(
        "flicker: output changes per second of held frames (not during a change of gesture), "
        "the first real change excepted; latency: true change (half-way shape) → output; "
        "smoothed: the session's 7-frame / 5-vote smoother; light: a 3-frame / 2-vote one"
    )


if __name__ == "__main__":
    run()
