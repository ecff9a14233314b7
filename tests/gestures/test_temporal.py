"""The temporal gesture model, labelled sequences, stream metrics, the sequence CSV and the
sample recorder."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from mimicrete import demonstrator as sy
from mimicrete import gestures as g
from mimicrete.cli import main as cli_main
from mimicrete.gestures import metrics as mt
from mimicrete.gestures import recorder as gr
from mimicrete.gestures import sequences as sq
from mimicrete.gestures import temporal as tp
from mimicrete.hands import model as hm

QUICK = {"svc__C": [10.0], "svc__gamma": [0.003]}


@pytest.fixture(scope="module")
def grip_temporal() -> tp.TemporalGestureModel:
    """A temporal grip model on 4 seeds (suction + grip episodes and a drill each)."""
    model, _ = tp.fit_temporal(sq.sequence_dataset("grip", range(4)), "grip", grid=QUICK)
    return model


def test_demonstrator_labels_each_frame_by_the_gesture_shown():
    ep = sy.synth_episode(sy.scene_from_env("screw", 3), 3)
    assert len(ep.gestures) == len(ep.t) == len(ep.changing)
    # the order of classes of a screw demonstration
    runs = [c for k, c in enumerate(ep.gestures) if k == 0 or c != ep.gestures[k - 1]]
    assert runs == [
        "opening_stopped",
        "closing_fixed",
        "closing_tightening",
        "closing_fixed",
        "opening_stopped",
    ]
    # the label switches half-way through the change of shape: inside a 'close' phase
    close = [k for k, p in enumerate(ep.phases) if p == "close"]
    labels = [ep.gestures[k] for k in close]
    assert labels[0] == "opening_stopped" and labels[-1] == "closing_fixed"
    assert all(ep.changing[k] for k in close)
    assert not any(ep.changing[k] for k, p in enumerate(ep.phases) if p in ("grasp", "start"))


def test_drill_shows_every_class_and_is_seeded():
    d = sq.drill_sequence("screw", 7)
    assert set(d.labels.tolist()) <= set(g.TASK_CLASSES["screw"])
    assert len(set(d.labels.tolist())) >= 4
    again = sq.drill_sequence("screw", 7)
    np.testing.assert_array_equal(d.joints, again.joints)
    # the shipped per-frame model reads the drill's held frames (the hand is the same model)
    model = g.load_default("screw", "per-frame")
    pred = model.predict_sequence(d.joints, d.handedness, d.layout, d.tracked)
    held = d.tracked & ~d.changing
    assert np.mean(pred[held] == d.labels[held]) > 0.98


def test_window_features_match_the_streaming_window():
    rng = np.random.default_rng(0)
    f = rng.normal(size=(20, 4))
    x = tp.window_features(f, 5, ("last", "median", "mean", "delta"))
    assert x.shape == (20, 16)
    # row 2 pads with frame 0: window [f0, f0, f0, f1, f2]
    win = np.stack([f[0], f[0], f[0], f[1], f[2]])
    np.testing.assert_allclose(x[2, 4:8], np.median(win, 0))
    np.testing.assert_allclose(x[2, 8:12], win.mean(0))
    np.testing.assert_allclose(x[2, 12:], np.median(win[2:], 0) - np.median(win[:3], 0))
    np.testing.assert_allclose(x[10, :4], f[10])


def test_temporal_streaming_equals_batch_and_round_trips(grip_temporal, tmp_path):
    model = grip_temporal
    assert model.kind == "temporal" and model.classes == g.TASK_CLASSES["grip"]
    seq = sq.drill_sequence("grip", 123)
    batch = model.predict_sequence(seq.joints, seq.handedness, seq.layout, seq.tracked)
    stream = mt.stream_outputs(model, seq)
    assert list(batch) == list(stream)
    # margins come with every answer
    model.reset()
    label, margin = model.predict_margin(seq.joints[0], seq.handedness, seq.layout)
    assert label in model.classes and margin is not None and np.isfinite(margin)
    # the window is the model's state: reset gives the same answers again
    model.reset()
    again = [model.predict_one(seq.joints[k], seq.handedness) for k in range(30)]
    assert again == [x for x in stream[:30]]
    # a degenerate hand gives None and does not enter the window
    assert model.predict_margin(np.zeros((26, 3))) == (None, None)
    path = model.save(tmp_path / "t.joblib")
    side = json.loads(Path(str(path) + ".json").read_text())
    assert side["kind"] == "temporal" and side["features"]["window_frames"] == model.window
    loaded = g.load_model(path)
    assert isinstance(loaded, tp.TemporalGestureModel)
    assert (loaded.window, loaded.parts) == (model.window, model.parts)
    assert list(mt.stream_outputs(loaded, seq)) == list(stream)
    # per-frame files still load as per-frame
    pf = g.load_default("grip", "per-frame")
    assert pf.kind == "per-frame" and not isinstance(pf, tp.TemporalGestureModel)


def test_temporal_flickers_no_more_than_per_frame_on_held_out_sequences(grip_temporal):
    """Held-out seeds (never trained on): the temporal model's raw output changes class while
    a gesture is held at most as often as the per-frame SVM's (which the glitches of these
    sequences do make flicker), and is as accurate."""
    seqs = sq.sequence_dataset("grip", [4242, 4243])
    pf = g.load_default("grip", "per-frame")
    r_pf = mt.evaluate(pf, seqs)
    r_tp = mt.evaluate(grip_temporal, seqs)
    assert r_pf["raw"]["flicker"] >= 3, r_pf  # there is flicker to beat
    assert r_tp["raw"]["flicker_per_s"] <= 0.5 * r_pf["raw"]["flicker_per_s"] + 0.02, (r_tp, r_pf)
    assert r_tp["raw"]["held_accuracy"] >= r_pf["raw"]["held_accuracy"] - 0.002
    # after the session's smoother neither flickers, and the temporal model is no slower
    assert r_tp["smoothed"]["flicker"] == 0 and r_pf["smoothed"]["flicker"] == 0
    assert r_tp["smoothed"]["missed"] == 0
    lat_tp, lat_pf = r_tp["smoothed"]["latency_ms_median"], r_pf["smoothed"]["latency_ms_median"]
    assert lat_tp <= lat_pf + 12.0


def test_stream_metrics_on_a_known_stream():
    n = 40
    labels = np.array(["a"] * 20 + ["b"] * 20)
    changing = np.zeros(n, bool)
    changing[18:22] = True
    seq = sq.GestureSequence(
        np.arange(n) / 10.0, np.zeros((n, 26, 3)), labels, np.ones(n, bool), changing
    )
    out = np.array(["a"] * 5 + ["b"] + ["a"] * 18 + ["b"] * 16, dtype=object)
    st = mt.stream_stats(seq, out)
    # a→b→a at frames 5-6 (2 flickers); the late real change at frame 24 is not flicker
    assert st.flicker == 2
    assert st.changes == 1 and st.missed == 0
    assert st.latencies == [pytest.approx(0.4)]  # true change at frame 20, output at 24
    assert st.correct == n - 1 - 4  # frame 5 wrong, frames 20-23 still 'a'
    assert st.held_frames == n - 4 and st.held_seconds == pytest.approx(3.6)


def test_sequence_csv_round_trip_and_plain_form_unchanged(tmp_path):
    seq = sq.drill_sequence("grip", 5)
    k = slice(0, 50)
    path = tmp_path / "s.csv"
    g.write_gesture_csv(
        path,
        seq.labels[k],
        seq.joints[k],
        sequence=np.repeat(["take1", "take2"], 25),
        t=seq.t[k],
        handedness="left",
    )
    assert path.read_text().startswith("label,sequence,t,handedness,c0,")
    d = g.read_gesture_csv(path)
    assert (d.layout, d.dims) == ("openxr", 3)
    np.testing.assert_allclose(d.joints, seq.joints[k], atol=1e-5)
    assert list(d.sequence[:26]) == ["take1"] * 25 + ["take2"]
    np.testing.assert_allclose(d.t, seq.t[k], atol=1e-6)
    assert set(d.hands()) == {"left"}
    seqs = d.sequences()
    assert [len(s) for s in seqs] == [25, 25] and seqs[0].handedness == "left"
    # no optional columns: the plain form exactly as before (no header), read back the same
    plain = tmp_path / "p.csv"
    g.write_gesture_csv(plain, seq.labels[k], seq.joints[k])
    first = plain.read_text().splitlines()[0].split(",")
    assert first[0] == seq.labels[0] and len(first) == 1 + 26 * 3
    p = g.read_gesture_csv(plain)
    assert p.sequence is None and p.t is None and p.handedness is None
    with pytest.raises(g.GestureDataError, match="no sequence column"):
        p.sequences()
    bad = tmp_path / "bad.csv"
    bad.write_text("label,handedness,c0\nopening,up," + ",".join(["0"] * 78) + "\n")
    with pytest.raises(g.GestureDataError, match=r"bad.csv:2: column 2: handedness"):
        g.read_gesture_csv(bad)


def test_cli_trains_and_evaluates_a_temporal_model_from_a_sequence_csv(tmp_path, capsys):
    seqs = sq.sequence_dataset("grip", range(20, 23))  # 9 sequences
    labels = np.concatenate([s.labels[s.tracked] for s in seqs])
    joints = np.concatenate([s.joints[s.tracked] for s in seqs])
    ids = np.concatenate([np.full(int(s.tracked.sum()), i) for i, s in enumerate(seqs)])
    t = np.concatenate([s.t[s.tracked] for s in seqs])
    hands = np.concatenate([np.full(int(s.tracked.sum()), s.handedness) for s in seqs])
    csv_path = tmp_path / "seqs.csv"
    g.write_gesture_csv(csv_path, labels, joints, sequence=ids, t=t, handedness=hands)
    out = tmp_path / "tm.joblib"
    argv = ["gesture", "train", "--temporal", "--data", str(csv_path), "--quick"]
    assert cli_main([*argv, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "temporal, window 9 frames" in text
    model = g.load_model(out)
    assert isinstance(model, tp.TemporalGestureModel) and model.info["n_sequences"] == 9
    assert model.info["test_accuracy"] > 0.97
    assert cli_main(["gesture", "eval", "--data", str(csv_path), "--model", str(out)]) == 0
    acc = float(capsys.readouterr().out.split("accuracy: ")[1].split(" %")[0])
    assert acc > 98.0
    # --temporal needs sequences: a plain CSV is refused with a clear message
    plain = tmp_path / "plain.csv"
    g.write_gesture_csv(plain, labels[:100], joints[:100])
    assert cli_main(["gesture", "train", "--temporal", "--data", str(plain), "--quick"]) == 2
    assert "no sequence column" in capsys.readouterr().err


def test_cli_trains_a_builtin_temporal_model(tmp_path, capsys):
    out = tmp_path / "gt.joblib"
    argv = ["gesture", "train", "--temporal", "--task", "screw", "--sequences", "6", "--quick"]
    assert cli_main([*argv, "--window", "5", "--out", str(out)]) == 0
    model = g.load_model(out)
    assert model.kind == "temporal" and model.window == 5
    assert model.classes == g.TASK_CLASSES["screw"] and model.info["cv_accuracy"] > 0.97


class _HandSource:
    """A parametric hand holding the prompted class's shape, 90 Hz, untracked now and then."""

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.t = 0.0
        self.shape = "opening"

    def prompt(self, label: str) -> None:
        self.shape = label

    def frames(self) -> Iterator[tuple[float, bool, np.ndarray]]:
        while True:
            self.t += 1 / 90
            j = hm.hand_joints(
                hm.jitter_shape(hm.GESTURE_SHAPES[self.shape], self.rng, 0.03),
                hm.random_rotation(self.rng),
                self.rng.uniform(-0.3, 0.3, 3),
            )
            yield self.t, bool(self.rng.random() > 0.1), j


def test_recorder_keeps_settled_spaced_tracked_samples_and_trains(tmp_path, capsys):
    src = _HandSource()
    rec = gr.record(
        src, [("closing", 40), ("opening", 40), ("fixed", 40)], layout="openxr", settle_s=0.3
    )
    assert rec.progress()["counts"] == {"closing": 40, "opening": 40, "fixed": 40}
    labels, joints, seq, t = rec.samples()
    for c, take in zip(("closing", "opening", "fixed"), (1, 2, 3), strict=True):
        ts = t[labels == c]
        assert np.all(np.diff(ts) >= 0.05 - 1e-9) and set(seq[labels == c]) == {take}
    # redo a class: its samples go, a new take starts after a new settle
    rec.start("fixed")
    assert rec.count("fixed") == 0 and not rec.done()
    t0 = src.t
    for f in src.frames():
        rec.push(*f)
        if rec.done("fixed"):
            break
    _, _, seq2, t2 = rec.samples()
    assert set(seq2[-40:]) == {4} and t2[-40] >= t0 + 0.3 - 1e-9
    # degenerate hands are not samples
    rec.start("opening")
    assert not rec.push(src.t + 5.0, True, np.zeros((26, 3)))
    rec.start("opening")
    src.prompt("opening")
    for f in src.frames():
        rec.push(*f)
        if rec.done():
            break
    path = rec.write_csv(tmp_path / "rec.csv")
    model, report = gr.train_samples(*rec.samples(), layout="openxr")
    assert report["test_accuracy"] > 0.95 and np.sum(report["confusion"]) == report["n_test"]
    out = tmp_path / "m.joblib"
    assert cli_main(["gesture", "train", "--data", str(path), "--quick", "--out", str(out)]) == 0
    assert "held-out accuracy" in capsys.readouterr().out
