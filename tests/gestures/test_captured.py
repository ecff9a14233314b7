"""The shipped gesture models on hands captured on a real headset (IWER's Quest-3 poses, read from
``web/node_modules/iwer``, which ``make test`` installs), and the pinch of the hand model.

The shipped models are fitted on synthetic hands only (``python -m mimicrete.gestures.shipped``);
these captured frames are never used to fit anything, so they are a held-out test."""

from __future__ import annotations

import numpy as np
import pytest

from mimicrete import gestures as g
from mimicrete.gestures import captured as cap
from mimicrete.gestures import shipped
from mimicrete.hands import layouts
from mimicrete.hands import model as hm

POSES = ("default", "pinch", "point")


def _bones(j: np.ndarray) -> np.ndarray:
    """Lengths of the phalanges of a WebXR hand (the thumb's three bones, each finger's proximal
    → tip; not the metacarpals, whose bases the tracker moves with the palm's arch)."""
    pairs = [(1, 2), (2, 3), (3, 4)] + [
        (k, k + 1)
        for f in ("index", "middle", "ring", "little")
        for k in cap.FINGER_JOINTS[f][1:-1]
    ]
    return np.array([np.linalg.norm(j[a] - j[b]) for a, b in pairs])


def test_iwer_poses_are_one_quest_skeleton_in_three_shapes():
    hands = {p: cap.iwer_pose(p) for p in POSES}
    for j in hands.values():
        assert j.shape == (25, 3) and np.isfinite(j).all()
    # one captured skeleton: phalanx lengths agree across the poses (to 0.1 mm)
    ref = _bones(hands["default"])
    for p in POSES:
        np.testing.assert_allclose(_bones(hands[p]), ref, atol=1e-4)
    # wrist → middle knuckle of an adult hand, and the shapes the poses are named for
    assert 0.08 < np.linalg.norm(hands["default"][11] - hands["default"][0]) < 0.11
    gap = {p: np.linalg.norm(hands[p][4] - hands[p][9]) for p in POSES}  # thumb tip ↔ index tip
    assert gap["pinch"] < 0.01 < 0.05 < gap["default"] and gap["point"] > 0.05
    index_out = {p: np.linalg.norm(hands[p][9] - hands[p][0]) for p in POSES}
    middle_out = {p: np.linalg.norm(hands[p][14] - hands[p][0]) for p in POSES}
    assert index_out["point"] > 0.16 and middle_out["point"] < 0.1 < 0.16 < middle_out["default"]


def test_right_hand_is_the_mirrored_left_as_iwer_makes_it():
    for p in POSES:
        m_l, m_r = cap.iwer_matrices(p, "left"), cap.iwer_matrices(p, "right")
        np.testing.assert_allclose(m_r[:, 0, 3], -m_l[:, 0, 3])
        np.testing.assert_allclose(m_r[:, 1:3, 3], m_l[:, 1:3, 3])
        np.testing.assert_allclose(np.linalg.det(m_r[:, :3, :3]), 1.0, atol=1e-4)
        # the same shape to the features (which mirror left hands)
        np.testing.assert_allclose(
            g.features_3d(cap.iwer_pose(p, "left"), "webxr", "left"),
            g.features_3d(cap.iwer_pose(p, "right"), "webxr", "right"),
            atol=1e-9,
        )


def test_splice_keeps_captured_fingers_and_is_identity_on_its_own_pose():
    for hand in ("left", "right"):
        np.testing.assert_allclose(
            cap.splice("pinch", {"little": "pinch"}, hand), cap.iwer_pose("pinch", hand), atol=1e-9
        )
        s = cap.splice("pinch", {"middle": "point", "little": "default"}, hand)
        point, relaxed, pinch = (cap.iwer_pose(p, hand) for p in ("point", "default", "pinch"))
        # untouched joints stay the palm pose's; spliced bones keep their captured lengths
        np.testing.assert_array_equal(s[:10], pinch[:10])
        np.testing.assert_array_equal(s[15:20], pinch[15:20])
        np.testing.assert_allclose(_bones(s), _bones(pinch), atol=1e-4)
        # the spliced middle finger is curled as in the point pose, the little one straight
        for k in range(10, 15):
            assert np.linalg.norm(s[k] - s[0]) == pytest.approx(
                np.linalg.norm(point[k] - point[0]), abs=0.006
            )
        assert np.linalg.norm(s[24] - s[0]) == pytest.approx(
            np.linalg.norm(relaxed[24] - relaxed[0]), abs=0.006
        )


def test_captured_sets_move_and_turn_the_hands():
    joints, labels, hands = cap.grip_captured_set(n=60, seed=3)
    assert joints.shape == (60, 25, 3) and set(hands) == {"left", "right"}
    assert [int((labels == c).sum()) for c in ("closing", "opening", "fixed")] == [20, 20, 20]
    wrists = joints[:, 0]
    assert np.ptp(wrists, axis=0).min() > 0.5  # spread over the workspace
    # turned: the wrist → middle knuckle direction points all over
    d = joints[:, 11] - joints[:, 0]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.linalg.norm(d.mean(0)) < 0.5
    sj, sl, _ = cap.screw_captured_set(n=50, seed=3)
    assert sj.shape == (50, 25, 3) and set(sl) == set(g.TASK_CLASSES["screw"])


@pytest.mark.parametrize("task", ["grip", "screw"])
def test_shipped_model_reads_captured_hands_per_frame(task):
    """Issue 23: ≥ 98 % per frame, every class ≥ 95 %, on the captured frames (IWER's pinch /
    relaxed / point for the 3-class model, their fingers spliced into the 5 screwing shapes),
    moved and turned, both hands, half with tracking noise. The model shipped before (fist =
    closing) read 62.5 % (pinch → opening) and 40 %."""
    model = g.load_default(task)
    got = shipped.captured_accuracy(model, task, seed=1)
    print(task, got["accuracy"], got["confusion"])
    assert got["accuracy"] >= 0.98
    assert min(got["per_class"].values()) >= 0.95


def test_pinch_shape_puts_the_thumb_tip_on_the_index_tip():
    rng = np.random.default_rng(4)
    for name in ("closing", "tightening", "loosening"):
        shapes = np.array([hm.sample_shape(name, rng).as_array() for _ in range(200)])
        shapes[:, 7] = 1.0
        j = hm.hand_joints_local_batch(shapes, 1.0, "right", hm.random_anatomy(rng, 200))
        gap = np.linalg.norm(j[:, 5] - j[:, 10], axis=1)
        off = np.linalg.norm(hm.random_anatomy(np.random.default_rng(0), 1000)[:, 9:12], axis=1)
        assert np.median(gap) < 0.012 and np.percentile(gap, 90) < np.percentile(off, 99) + 0.01
        # bone lengths survive the thumb's solve
        for a, b in ((2, 3), (3, 4), (4, 5)):
            length = np.linalg.norm(j[:, a] - j[:, b], axis=1)
            assert np.ptp(length) < 0.02
    # open hands and points keep the thumb away from the index tip
    for name in ("opening", "fixed"):
        shapes = np.array([hm.sample_shape(name, rng).as_array() for _ in range(200)])
        j = hm.hand_joints_local_batch(shapes, 1.0, "left", hm.random_anatomy(rng, 200))
        assert np.linalg.norm(j[:, 5] - j[:, 10], axis=1).min() > 0.025


def test_old_seven_number_shapes_still_build():
    s = hm.GESTURE_SHAPES["opening"]
    seven = s.as_array()[:7]
    np.testing.assert_array_equal(
        hm.hand_joints_local_batch(seven[None])[0], hm.hand_joints_local(s)
    )
    assert hm.HandShape.from_array(seven) == s
    with pytest.raises(ValueError, match="9 \\(or 7\\) numbers"):
        hm.hand_joints_local_batch(np.zeros((1, 5)))
    # the average anatomy is the hand without one
    np.testing.assert_array_equal(
        hm.hand_joints_local(s, anatomy=np.zeros(hm.N_ANATOMY)), hm.hand_joints_local(s)
    )
    assert layouts.to_layout(hm.hand_joints_local(s), "webxr").shape == (25, 3)


def test_keypoint_check_reads_the_public_csv_format(tmp_path):
    """The 2-D check's mechanics on rows in the public keypoint.csv form (wrist-relative image
    points / max |v|; 0 Open, 1 Close, 2 Pointer), made here from the hand model seen by a
    camera: open hands and points read right, the fists are only counted."""
    rng = np.random.default_rng(8)
    rows = []
    for label, shape in ((0, "opening"), (1, "fist"), (2, "fixed")):
        for _ in range(40):
            j = hm.hand_joints(
                hm.jitter_shape(hm.GESTURE_SHAPES[shape], rng, 0.03),
                hm.rotation_matrix([0, 0, 1], rng.uniform(-0.5, 0.5))
                @ hm.rotation_matrix([0, 1, 0], rng.uniform(-0.5, 0.5)),
                np.zeros(3),
            )
            pix = layouts.to_layout(j, "mediapipe")[:, :2] * np.array([1.0, -1.0])
            rel = (pix - pix[0]).ravel()
            rows.append(",".join([str(label), *(f"{v:.6f}" for v in rel / np.abs(rel).max())]))
    path = tmp_path / "keypoint.csv"
    path.write_text("\ufeff" + "\n".join(rows) + "\n")
    got = cap.keypoint_check(path, per_class=150)
    assert set(got["per_class"]) == {"opening", "fixed"}
    assert got["per_class"]["opening"] > 0.8 and got["per_class"]["fixed"] > 0.8
    assert sum(got["counts"][1].values()) == 40 and 0.8 < got["synthetic_heldout"] <= 1.0
