"""Hand model, gesture features, SVM models, gesture CSVs and the stream smoother."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete import gestures as g
from mimicrete.cli import main as cli_main
from mimicrete.hands import layouts
from mimicrete.hands import model as hm

SHAPES = list(hm.GESTURE_SHAPES)


def _rot(seed: int) -> np.ndarray:
    return hm.random_rotation(np.random.default_rng(seed))


# ---------------------------------------------------------------- hand model


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scale=st.floats(0.7, 1.3),
    hand=st.sampled_from(["left", "right"]),
    shape=st.sampled_from(SHAPES),
)
def test_hand_frame_is_the_wrist_rotation(seed, scale, hand, shape):
    rot = _rot(seed)
    pos = np.random.default_rng(seed).normal(size=3)
    j = hm.hand_joints(hm.GESTURE_SHAPES[shape], rot, pos, scale, hand)
    frame, origin = hm.hand_frame(j[1], j[7], j[12])
    np.testing.assert_allclose(frame, rot, atol=1e-9)
    np.testing.assert_allclose(origin, pos, atol=1e-12)
    # hand size: wrist -> middle proximal is 8.6 cm at scale 1
    assert np.linalg.norm(j[12] - j[1]) == pytest.approx(0.086 * scale, rel=1e-9)


def test_hand_dimensions_and_gesture_geometry():
    open_ = hm.hand_joints_local(hm.GESTURE_SHAPES["opening"])
    pinch = hm.hand_joints_local(hm.GESTURE_SHAPES["closing"])
    fist = hm.hand_joints_local(hm.GESTURE_SHAPES["tightening"])  # a pinch, the rest curled
    point = hm.hand_joints_local(hm.GESTURE_SHAPES["fixed"])
    # wrist -> middle fingertip of an adult open hand: 17-20 cm
    assert 0.17 < np.linalg.norm(open_[15] - open_[1]) < 0.20
    # the pinch: thumb tip on the index tip, the index bent, the other fingers loose
    assert np.linalg.norm(pinch[5] - pinch[10]) < 1e-3
    assert np.linalg.norm(open_[5] - open_[10]) > 0.06
    assert np.linalg.norm(pinch[10] - pinch[1]) < 0.15 < np.linalg.norm(pinch[15] - pinch[1])
    # curled fingers come within 9 cm of the wrist (a fist: all four); pointing keeps the index out
    for tip in (15, 20, 25):
        assert np.linalg.norm(fist[tip] - fist[1]) < 0.09
    real_fist = hm.hand_joints_local(hm.GESTURE_SHAPES["fist"])
    for tip in (10, 15, 20, 25):
        assert np.linalg.norm(real_fist[tip] - real_fist[1]) < 0.09
    assert np.linalg.norm(point[10] - point[1]) > 0.16
    assert np.linalg.norm(point[15] - point[1]) < 0.09
    # fingers curl toward the palm (-Z for a right hand), the left hand toward +Z
    assert fist[12:16, 2].min() < -0.03
    assert (
        hm.hand_joints_local(hm.GESTURE_SHAPES["tightening"], handedness="left")[12:16, 2].max()
        > 0.03
    )
    # bone lengths do not change with curl or pinch
    for a, b in ((7, 8), (8, 9), (9, 10), (3, 4), (4, 5)):
        for other in (fist, pinch):
            assert np.linalg.norm(open_[a] - open_[b]) == pytest.approx(
                np.linalg.norm(other[a] - other[b]), rel=1e-9
            )


def test_layout_maps_keep_the_frame_joints():
    j = hm.hand_joints(hm.GESTURE_SHAPES["opening"], _rot(3), np.array([0.1, 1.2, -0.3]))
    w, i, m = j[1], j[7], j[12]
    for layout, n in layouts.LAYOUT_JOINTS.items():
        out = layouts.to_layout(j, layout)
        assert out.shape == (n, 3)
        fw, fi, fm = layouts.FRAME_JOINTS[layout]
        np.testing.assert_array_equal(out[fw], w)
        np.testing.assert_array_equal(out[fi], i)
        np.testing.assert_array_equal(out[fm], m)
        np.testing.assert_array_equal(
            layouts.canonical21(out, layout), j[list(layouts.MEDIAPIPE_FROM_OPENXR)]
        )
    ovr = layouts.to_layout(j, "meta_ovr")
    np.testing.assert_array_equal(ovr[19:24], j[[5, 10, 15, 20, 25]])  # tips
    np.testing.assert_array_equal(ovr[15], j[21])  # Pinky0 = little metacarpal
    with pytest.raises(ValueError, match="unknown hand layout"):
        layouts.to_layout(j, "kinect")


def test_degenerate_frame_raises():
    with pytest.raises(ValueError, match="degenerate"):
        hm.hand_frame(np.zeros(3), np.array([0.0, 1.0, 0.0]), np.array([0.0, 2.0, 0.0]))


# ---------------------------------------------------------------- features


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    scale=st.floats(0.75, 1.25),
    shape=st.sampled_from(SHAPES),
    layout=st.sampled_from(sorted(layouts.LAYOUT_JOINTS)),
)
def test_features_3d_invariant_to_pose_size_hand_and_layout(seed, scale, shape, layout):
    s = hm.GESTURE_SHAPES[shape]
    ref = g.features_3d(hm.hand_joints_local(s), "openxr", "right")
    rng = np.random.default_rng(seed)
    for hand in ("right", "left"):
        j = hm.hand_joints(s, hm.random_rotation(rng), rng.normal(size=3), scale, hand)
        f = g.features_3d(layouts.to_layout(j, layout), layout, hand)
        np.testing.assert_allclose(f, ref, atol=1e-9)


def test_features_3d_separate_gestures_and_batch_matches_single():
    js = np.array([hm.hand_joints_local(hm.GESTURE_SHAPES[s]) for s in SHAPES])
    fs = g.features_3d(js, "openxr", "right")
    assert fs.shape == (len(SHAPES), 60)
    for a in range(len(SHAPES)):
        np.testing.assert_allclose(fs[a], g.features_3d(js[a]), atol=1e-12)
        for b in range(a):
            assert np.linalg.norm(fs[a] - fs[b]) > 0.3, (SHAPES[a], SHAPES[b])
    # a degenerate hand gives NaN, not an exception
    assert np.isnan(g.features_3d(np.zeros((26, 3)))).all()


def _project(joints3d: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Pinhole camera image landmarks (x right, y down, pixels) of MediaPipe-ordered joints."""
    cam = joints3d[..., :] - np.array([0.0, 0.0, -0.6])  # camera 60 cm in front, looking at -Z
    f = rng.uniform(500, 900)
    x = f * cam[..., 0] / -cam[..., 2] + 320
    y = -f * cam[..., 1] / -cam[..., 2] + 240
    return np.stack([x, y], axis=-1)


def _keypoint_row(pix: np.ndarray) -> np.ndarray:
    """The public keypoint.csv pre-processing: relative to the wrist, flattened, / max |v|."""
    rel = (pix - pix[0]).ravel()
    return rel / np.abs(rel).max()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), shape=st.sampled_from(SHAPES))
def test_features_2d_invariant_to_image_similarity(seed, shape):
    rng = np.random.default_rng(seed)
    pts = layouts.to_layout(hm.hand_joints_local(hm.GESTURE_SHAPES[shape]), "mediapipe")[:, :2]
    ang = rng.uniform(-np.pi, np.pi)
    r = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
    moved = rng.uniform(0.1, 10) * pts @ r.T + rng.normal(size=2)
    np.testing.assert_allclose(g.features_2d(moved), g.features_2d(pts), atol=1e-9)
    f = g.features_2d(pts)
    assert f.shape == (40,)
    np.testing.assert_allclose(f[2 * 8 : 2 * 8 + 2], [0.0, 1.0], atol=1e-12)  # middle MCP on +y


# ---------------------------------------------------------------- models


def test_builtin_data_is_paper_sized_and_seeded():
    j, y, h = g.synthetic_dataset("grip", seed=5)
    assert j.shape == (827, 26, 3)
    assert [int((y == c).sum()) for c in g.TASK_CLASSES["grip"]] == [290, 274, 263]
    assert set(h) == {"left", "right"}
    j2, y2, _ = g.synthetic_dataset("grip", seed=5)
    np.testing.assert_array_equal(j, j2)
    np.testing.assert_array_equal(y, y2)
    js, ys, _ = g.synthetic_dataset("screw", seed=0, layout="webxr")
    assert js.shape == (6925, 25, 3)
    assert [int((ys == c).sum()) for c in g.TASK_CLASSES["screw"]] == list(g.PAPER_COUNTS["screw"])


def test_fit_quick_grid_is_accurate_but_not_trivially():
    model, (xte, yte) = g.train_builtin(
        "grip", seed=1, grid={"svc__C": [10.0], "svc__gamma": [0.01]}
    )
    acc = model.info["test_accuracy"]
    assert model.info["n_test"] == 166 and model.info["n_train"] == 661
    assert 0.90 <= acc <= 1.0
    # the ambiguous in-between shapes make the built-in data not separable by a nearest mean
    joints, labels, hands = g.synthetic_dataset("grip", seed=1)
    feats = g.features_3d(joints, "openxr", hands)
    means = {c: feats[labels == c].mean(0) for c in g.TASK_CLASSES["grip"]}
    nearest = np.array([min(means, key=lambda c, f=f: np.linalg.norm(f - means[c])) for f in feats])
    assert np.mean(nearest == labels) < 0.99


@pytest.mark.parametrize("task", ["grip", "screw"])
def test_shipped_models(task):
    model = g.load_default(task)
    assert model.classes == g.TASK_CLASSES[task]
    assert model.info["test_accuracy"] > 0.95
    assert model.info["n_test"] == {"grip": 166, "screw": 2078}[task]
    rng = np.random.default_rng(11)
    for label in model.classes:
        for hand in ("right", "left"):
            shape = hm.GESTURE_SHAPES[g.CLASS_SHAPE[label]]
            j = hm.hand_joints(
                shape, hm.random_rotation(rng), rng.normal(size=3), rng.uniform(0.85, 1.15), hand
            )
            for layout in layouts.LAYOUT_JOINTS:
                assert model.predict_one(layouts.to_layout(j, layout), hand, layout) == label
    assert model.predict_one(np.zeros((26, 3))) is None


def test_save_load_roundtrip_and_version_warning(tmp_path):
    model, (xte, _) = g.train_builtin("grip", seed=2, grid={"svc__C": [10.0], "svc__gamma": [0.01]})
    path = model.save(tmp_path / "m.joblib")
    side = json.loads((tmp_path / "m.joblib.json").read_text())
    assert side["features"]["n_features"] == 60
    assert side["versions"]["sklearn"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = g.load_model(path)
    np.testing.assert_array_equal(back.pipeline.predict(xte), model.pipeline.predict(xte))
    side["versions"]["sklearn"] = "0.0.1"
    (tmp_path / "m.joblib.json").write_text(json.dumps(side))
    with pytest.warns(RuntimeWarning, match="sklearn 0.0.1"):
        g.load_model(path)


# ---------------------------------------------------------------- CSV


def _mediapipe_2d_csv(path, n_per_class: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    rows = []
    # keypoint.csv labels: 0 Open, 1 Close, 2 Pointer
    for label, shape in enumerate(["opening", "closing", "fixed"]):
        for _ in range(n_per_class):
            # a hand held up in front of a camera, palm or back toward it
            flip = np.pi * (rng.random() < 0.3)
            j = hm.hand_joints(
                hm.jitter_shape(hm.GESTURE_SHAPES[shape], rng),
                hm.rotation_matrix([0, 0, 1], rng.uniform(-0.6, 0.6))
                @ hm.rotation_matrix([0, 1, 0], rng.uniform(-0.5, 0.5) + flip),
                np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), -0.2]),
                rng.uniform(0.85, 1.15),
            )
            pix = _project(layouts.to_layout(j, "mediapipe"), rng)
            rows.append([str(label), *(f"{v:.6f}" for v in _keypoint_row(pix))])
    path.write_text("\ufeff" + "\n".join(",".join(r) for r in rows) + "\n")


def test_mediapipe_keypoint_csv_2d_trains(tmp_path):
    csv_path = tmp_path / "keypoint.csv"
    _mediapipe_2d_csv(csv_path, 120, seed=0)
    data = g.read_gesture_csv(csv_path, label_names=["open", "close", "pointer"])
    assert (data.layout, data.dims) == ("mediapipe", 2)
    assert data.joints.shape == (360, 21, 2)
    assert set(data.labels) == {"open", "close", "pointer"}
    feats = g.featurize(data.joints, data.layout, data.dims)
    _, info, _ = g.fit(
        feats, data.labels, test_size=0.25, seed=0, grid={"svc__C": [10.0], "svc__gamma": ["scale"]}
    )
    assert info["test_accuracy"] > 0.9


def test_csv_3d_any_layout_and_cli(tmp_path, capsys):
    # right hands only: a user CSV carries no handedness
    y = np.repeat(np.array(g.TASK_CLASSES["grip"]), 60)
    rng = np.random.default_rng(0)
    j = np.array(
        [
            layouts.to_layout(
                hm.hand_joints(
                    hm.jitter_shape(hm.GESTURE_SHAPES[c], rng), hm.random_rotation(rng), np.zeros(3)
                ),
                "webxr",
            )
            for c in y
        ]
    )
    path = tmp_path / "webxr.csv"
    g.write_gesture_csv(path, y, j)
    data = g.read_gesture_csv(path)
    assert (data.layout, data.dims) == ("webxr", 3)
    np.testing.assert_allclose(data.joints, j, rtol=1e-5, atol=1e-6)
    out = tmp_path / "custom.joblib"
    assert cli_main(["gesture", "train", "--data", str(path), "--out", str(out), "--quick"]) == 0
    text = capsys.readouterr().out
    assert "held-out accuracy" in text and "closing" in text
    assert cli_main(["gesture", "eval", "--data", str(path), "--model", str(out)]) == 0
    text = capsys.readouterr().out
    assert "webxr.csv (every row, no split) accuracy: " in text
    acc = float(text.split("accuracy: ")[1].split(" %")[0])
    assert acc > 95.0


@pytest.mark.parametrize(
    ("content", "match"),
    [
        ("a," + ",".join(["0.1"] * 42) + "\nb," + ",".join(["0.1"] * 41) + "\n", r":2: 41 coord"),
        ("a," + ",".join(["0.1"] * 41) + ",zz\n", r":1: column 43: not a number: 'zz'"),
        ("a," + ",".join(["0.1"] * 10) + "\n", r":1: 10 coordinates .* fit no layout"),
        ("\n\na," + ",".join(["nan"] * 42) + "\n", r":3: column 2: not finite"),
        (",1,2\n", r":1: empty label"),
        ("", r":1: no data rows"),
    ],
)
def test_csv_errors_name_file_and_line(tmp_path, content, match):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(g.GestureDataError, match=match) as e:
        g.read_gesture_csv(path)
    assert str(e.value).startswith(str(path) + ":")


def test_csv_layout_mismatch_and_label_names(tmp_path):
    path = tmp_path / "x.csv"
    path.write_text("3," + ",".join(["0.5"] * 42) + "\n")
    with pytest.raises(g.GestureDataError, match=r":1: 42 coordinates .* layout openxr needs 52"):
        g.read_gesture_csv(path, layout="openxr")
    with pytest.raises(g.GestureDataError, match=r":1: label '3' is not an index"):
        g.read_gesture_csv(path, label_names=["a", "b"])


# ---------------------------------------------------------------- smoother


def test_smoother_ignores_single_misreads_and_switches_on_real_changes():
    s = g.GestureSmoother(n=7, k=5, initial="opening")
    seq = ["opening"] * 20 + ["closing"] * 30 + ["opening"] * 20
    noisy = list(seq)
    for i in (5, 11, 25, 31, 38, 44, 60, 66):  # isolated single-frame errors, 6+ frames apart
        noisy[i] = "fixed" if noisy[i] != "fixed" else "opening"
    out = [s.update(x) for x in noisy]
    assert "fixed" not in out
    first_closing = out.index("closing")
    assert 20 + 4 <= first_closing <= 20 + 6  # k frames of latency (+1 if a misread falls in)
    assert out[first_closing:50] == ["closing"] * (50 - first_closing)
    # untracked frames hold the output
    assert s.update(None) == out[-1]


@settings(max_examples=200, deadline=None)
@given(
    truth=st.lists(st.sampled_from(["closing", "opening", "fixed"]), min_size=1, max_size=6),
    runs=st.lists(st.integers(8, 30), min_size=6, max_size=6),
    errors=st.lists(st.integers(0, 10_000), max_size=20),
    wrong=st.sampled_from(["closing", "opening", "fixed", "junk"]),
)
def test_smoother_property_isolated_errors_never_flip(truth, runs, errors, wrong):
    n, k = 7, 5
    seq = [lab for lab, r in zip(truth, runs, strict=False) for _ in range(r)]
    noisy = list(seq)
    last = -100
    for e in sorted(errors):
        i = e % len(seq)
        if i - last >= n and noisy[i] != wrong:  # at most one error in any window of n
            noisy[i] = wrong
            last = i
    s = g.GestureSmoother(n=n, k=k, initial=seq[0])
    out = [s.update(x) for x in noisy]
    # the output is always a label that really was being shown, never the misread one
    for i, o in enumerate(out):
        assert o in seq[max(0, i - n - 1) : i + 1]
    # and after each run (>= 8 frames) settles, it equals the truth
    assert out[-1] == seq[-1]


def test_smoother_validates():
    with pytest.raises(ValueError):
        g.GestureSmoother(n=3, k=4)


@pytest.mark.parametrize("task", ["grip", "screw"])
def test_fast_single_sample_path_matches_sklearn(task):
    model = g.load_default(task)
    joints, _, hands = g.synthetic_dataset(task, seed=21, counts=(120,) * len(model.classes))
    feats = g.features_3d(joints, "openxr", hands)
    ref = model.pipeline.predict(feats)
    fast = g.FastRbfSvc.from_pipeline(model.pipeline)
    got = [fast.predict_one(f) for f in feats]
    assert list(ref) == got
    # and the per-frame entry point (single-sample features + fast SVC) agrees too
    assert [model.predict_one(j, h) for j, h in zip(joints[:100], hands[:100], strict=True)] == (
        list(ref[:100])
    )


def test_cli_2d_keypoint_csv_label_names_carry_to_eval(tmp_path, capsys):
    csv_path = tmp_path / "keypoint.csv"
    _mediapipe_2d_csv(csv_path, 60, seed=1)
    out = tmp_path / "kp.joblib"
    argv = [
        "gesture",
        "train",
        "--data",
        str(csv_path),
        "--label-names",
        "open,close,pointer",
        "--quick",
    ]
    assert cli_main([*argv, "--out", str(out)]) == 0
    side = json.loads((tmp_path / "kp.joblib.json").read_text())
    assert side["features"]["kind"] == "2d" and side["info"]["label_names"][2] == "pointer"
    capsys.readouterr()
    assert cli_main(["gesture", "eval", "--data", str(csv_path), "--model", str(out)]) == 0
    text = capsys.readouterr().out
    assert "pointer" in text and float(text.split("accuracy: ")[1].split(" %")[0]) > 90.0
    # a 3-D model refuses 2-D data with a clear message
    assert cli_main(["gesture", "eval", "--data", str(csv_path), "--task", "grip"]) == 2


def test_margin_agrees_with_the_pipeline_and_is_positive_for_the_winner():
    """The per-frame path's class equals scikit-learn's, and its margin is the winner's smallest
    one-vs-one decision value (≥ 0 except where libsvm breaks a tie)."""
    model = g.load_default("grip")
    joints, labels, hands = g.synthetic_dataset("grip", seed=5, counts=(40, 40, 40))
    feats = g.features_3d(joints, "openxr", hands)
    fast = g.FastRbfSvc.from_pipeline(model.pipeline)
    for f, h, j in zip(feats, hands, joints, strict=True):
        label, margin = model.predict_margin(j, h, "openxr")
        assert label == model.pipeline.predict(f[None])[0] == fast.predict_one(f)
        assert margin is not None and np.isfinite(margin)
    margins = [model.predict_margin(j, h, "openxr")[1] for j, h in zip(joints, hands, strict=True)]
    assert np.median(margins) > 0.5
