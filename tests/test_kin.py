"""mc.kin: round trips, errors, shapes and messages of the ur3-kin bindings."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import mimicrete as mc

kin = mc.kin
MODELS = ["ur3", "ur3e", "ur5", "ur5e", "ur10", "ur10e"]


def pose_err(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    dp = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
    r = a[:3, :3].T @ b[:3, :3]
    da = math.acos(max(-1.0, min(1.0, (np.trace(r) - 1.0) / 2.0)))
    return dp, da


def test_models_listed():
    assert sorted(kin.MODELS) == sorted(MODELS)


def test_ur3_zero_pose_geometry():
    t = kin.fk(np.zeros(6))
    d = kin.dh("ur3")
    assert t.shape == (4, 4) and t.dtype == np.float64
    np.testing.assert_allclose(
        t[:3, 3], [d["a2"] + d["a3"], -(d["d4"] + d["d6"]), d["d1"] - d["d5"]], atol=1e-12
    )
    np.testing.assert_allclose(t[:3, 2], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(t[3], [0, 0, 0, 1])
    assert d["a2"] == -0.24365 and d["d1"] == 0.1519


@pytest.mark.parametrize("model", MODELS)
def test_round_trips_every_model(model):
    rng = np.random.default_rng(1)
    for _ in range(200):
        q = rng.uniform(-np.pi, np.pi, 6)
        t = kin.fk(q, model=model)
        for seed in (None, q + rng.normal(0, 0.1, 6)):
            s = kin.ik(t, seed=seed, model=model)
            assert s.shape == (6,)
            assert np.all(np.abs(s) <= np.pi)
            dp, da = pose_err(kin.fk(s, model=model), t)
            assert dp < 1e-6 and da < 1e-6
        sols = kin.ik_all(t, model=model)
        assert 1 <= sols.shape[0] <= 8 and sols.shape[1] == 6
        for s in sols:
            dp, da = pose_err(kin.fk(s, model=model), t)
            assert dp < 1e-6 and da < 1e-6
        # the true q is one of the branches (per-joint wrapped difference)
        diff = (sols - q + np.pi) % (2 * np.pi) - np.pi
        assert np.min(np.linalg.norm(diff, axis=1)) < 1e-6


def test_warm_start_returns_the_seeded_branch():
    q = np.array([0.4, -1.2, 1.0, -1.3, -1.5, 0.2])
    t = kin.fk(q)
    np.testing.assert_allclose(kin.ik(t, seed=q + 0.1), q, atol=1e-8)
    # another branch as seed → that branch
    for other in kin.ik_all(t):
        np.testing.assert_allclose(kin.ik(t, seed=other + 0.01), other, atol=1e-7)


def test_paper_gauss_newton_alone():
    q = np.array([0.4, -1.2, 1.0, -1.3, -1.5, 0.2])
    t = kin.fk(q)
    np.testing.assert_allclose(kin.ik_gn(t, q + 0.1), q, atol=1e-8)
    with pytest.raises(mc.IkError, match="did not converge"):
        kin.ik_gn(t, np.zeros(6), max_iters=1)


def test_ik_batch_matches_single_and_flags_failures():
    rng = np.random.default_rng(2)
    qs = rng.uniform(-np.pi, np.pi, (500, 6))
    ts = kin.fk_batch(qs)
    assert ts.shape == (500, 4, 4)
    np.testing.assert_allclose(ts[7], kin.fk(qs[7]), atol=1e-15)
    ts[3, 0, 3] = 5.0  # unreachable
    ts[4, :3, :3] *= 2.0  # not a rigid transform
    seeds = qs + rng.normal(0, 0.1, qs.shape)
    for s in (None, seeds):
        q, ok = kin.ik_batch(ts, s)
        assert q.shape == (500, 6) and ok.shape == (500,) and ok.dtype == bool
        assert not ok[3] and not ok[4] and np.isnan(q[3]).all() and np.isnan(q[4]).all()
        assert ok.sum() == 498
        for i in (0, 1, 2, 100, 499):
            np.testing.assert_allclose(q[i], kin.ik(ts[i], None if s is None else s[i]), atol=1e-12)
        for i in np.flatnonzero(ok)[::25]:
            dp, da = pose_err(kin.fk(q[i]), ts[i])
            assert dp < 1e-6 and da < 1e-6
    q1, _ = kin.ik_batch(ts, seeds, threads=1)
    q2, _ = kin.ik_batch(ts, seeds, threads=2)
    np.testing.assert_array_equal(q1, q2)


def test_jacobian_against_finite_differences():
    rng = np.random.default_rng(3)
    q = rng.uniform(-np.pi, np.pi, 6)
    j = kin.jacobian(q)
    assert j.shape == (6, 6)
    h = 1e-6
    for i in range(6):
        dq = np.zeros(6)
        dq[i] = h
        tp, tm = kin.fk(q + dq), kin.fk(q - dq)
        np.testing.assert_allclose(j[:3, i], (tp[:3, 3] - tm[:3, 3]) / (2 * h), atol=1e-6)
        w = tp[:3, :3] @ tm[:3, :3].T  # ≈ I + 2h [ω]×
        omega = np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]]) / (4 * h)
        np.testing.assert_allclose(j[3:, i], omega, atol=1e-6)


def test_errors_and_messages():
    t = kin.fk(np.zeros(6))
    with pytest.raises(mc.IkError, match="unreachable"):
        kin.ik(np.array([[1, 0, 0, 2.0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]))
    assert issubclass(mc.IkError, mc.MimicreteError)
    with pytest.raises(ValueError, match=r"shape \(4, 4\)"):
        kin.ik(np.eye(3))
    with pytest.raises(ValueError, match=r"seed must have shape \(6,\)"):
        kin.ik(t, seed=np.zeros(7))
    with pytest.raises(ValueError, match=r"q must have shape \(6,\)"):
        kin.fk(np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"\(N, 4, 4\)"):
        kin.ik_batch(np.zeros((3, 4, 3)))
    with pytest.raises(ValueError, match=r"seeds must have shape \(2, 6\)"):
        kin.ik_batch(np.stack([t, t]), np.zeros((3, 6)))
    with pytest.raises(ValueError, match="unknown robot model"):
        kin.fk(np.zeros(6), model="ur7")
    bad = t.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        kin.ik(bad)
    refl = t.copy()
    refl[:3, 0] *= -1
    with pytest.raises(ValueError, match="determinant"):
        kin.ik(refl)
    with pytest.raises(ValueError, match="numeric"):
        kin.fk(["a"] * 6)
    with pytest.raises(ValueError, match=r"seed holds a NaN"):
        kin.ik(t, seed=np.full(6, np.inf))
    with pytest.raises(ValueError, match=r"q holds a NaN"):
        kin.fk(np.array([0, 0, np.nan, 0, 0, 0]))
    with pytest.raises(ValueError, match=r"q holds a NaN"):
        kin.fk_batch(np.full((2, 6), np.inf))
    with pytest.raises(ValueError, match=r"q holds a NaN"):
        kin.jacobian(np.full(6, np.nan))
    far = np.eye(4)
    far[0, 3] = 2.0
    assert kin.ik_all(far).shape == (0, 6)


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, (4, 4), elements=st.floats(allow_nan=False, allow_infinity=False)))
def test_arbitrary_finite_matrices_never_crash(m):
    try:
        q = kin.ik(m)
    except (mc.IkError, ValueError):
        return
    assert np.all(np.isfinite(q)) and np.all(np.abs(q) <= np.pi)
    dp, da = pose_err(kin.fk(q), m)
    assert dp < 1e-6 and da < 1e-6


@settings(max_examples=200, deadline=None)
@given(arrays(np.float64, 6, elements=st.floats(-50, 50)))
def test_fk_periodic_and_ik_wrapped(q):
    t = kin.fk(q)
    qw = (q + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(kin.fk(qw), t, atol=1e-9)
    s = kin.ik(t, seed=q)
    assert np.all(np.abs(s) <= np.pi)


def test_hand_to_target_palm_down_and_handedness():
    # OpenXR, default calibration: palm down, fingers forward (−Z), 0.4 m in front/below the head.
    w = np.array([0.0, -0.4, -0.4])
    m = np.array([0.0, -0.4, -0.49])
    i_right = np.array([-0.022, -0.4, -0.485])
    i_left = np.array([0.022, -0.4, -0.485])
    tr = kin.hand_to_target(w, i_right, m)
    tl = kin.hand_to_target(w, i_left, m, handedness="left")
    for t in (tr, tl):
        np.testing.assert_allclose(t[:3, 3], [0.3, 0.0, 0.2], atol=1e-12)
        np.testing.assert_allclose(t[:3, 2], [0, 0, -1], atol=1e-12)  # tool points down
        np.testing.assert_allclose(t[:3, 0], [1, 0, 0], atol=1e-12)  # tool x along the fingers
    # the default calibration as an explicit object gives the same; scale and robot_base space
    np.testing.assert_allclose(kin.hand_to_target(w, i_right, m, calibration=kin.Calibration()), tr)
    cal = {"base_from_space": np.eye(4), "scale": 1.0, "space": "robot_base"}
    t = kin.hand_to_target([0.3, 0, 0.2], [0.385, 0.022, 0.2], [0.39, 0, 0.2], calibration=cal)
    np.testing.assert_allclose(t[:3, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(kin.points_to_base(w), [0.3, 0.0, 0.2], atol=1e-12)
    np.testing.assert_allclose(
        kin.points_to_base(np.stack([w, m]), kin.Calibration(scale=2.0)),
        [[0.7, 0.0, -0.2], [0.88, 0.0, -0.2]],
        atol=1e-12,
    )
    # the target is reachable for the UR3 and IK solves it
    q = kin.ik(tr)
    dp, da = pose_err(kin.fk(q), tr)
    assert dp < 1e-6 and da < 1e-6


def test_hand_to_target_errors_and_batch():
    w = np.zeros(3)
    with pytest.raises(ValueError, match="degenerate hand"):
        kin.hand_to_target(w, [0, 0.05, 0], [0, 0.09, 0])
    with pytest.raises(ValueError, match="degenerate hand"):
        kin.hand_to_target(w, [0, 0.09, 0], [0, 0.09, 0])
    with pytest.raises(ValueError, match="unknown handedness"):
        kin.hand_to_target(w, [0.02, 0.08, 0], [0, 0.09, 0], handedness="both")
    with pytest.raises(ValueError, match=r"wrist must have shape \(3,\)"):
        kin.hand_to_target(np.zeros(2), [0.02, 0.08, 0], [0, 0.09, 0])
    with pytest.raises(ValueError, match="unknown coordinate space"):
        kin.hand_to_target(w, [0.02, 0.08, 0], [0, 0.09, 0], calibration={"space": "mars"})
    ws = np.zeros((3, 3))
    ids = np.array([[0.02, 0.08, 0], [0, 0.05, 0], [0.02, 0.08, 0.01]])
    ms = np.tile([0, 0.09, 0], (3, 1))
    t, ok = kin.hand_to_target_batch(ws, ids, ms, "right")
    assert t.shape == (3, 4, 4) and ok.tolist() == [True, False, True]
    np.testing.assert_allclose(t[0], kin.hand_to_target(ws[0], ids[0], ms[0]))
    np.testing.assert_allclose(t[1], np.eye(4))


def test_urdf_is_valid_and_matches_fk():
    for model in MODELS:
        root = ET.fromstring(kin.urdf(model))
        assert root.tag == "robot" and root.get("name") == model
        joints = root.findall("joint")
        assert [j.get("name") for j in joints if j.get("type") == "revolute"] == [
            "shoulder_pan_joint",
            "shoulder_lift_joint",
            "elbow_joint",
            "wrist_1_joint",
            "wrist_2_joint",
            "wrist_3_joint",
        ]
        # FK along the URDF chain with numpy == kin.fk
        q = np.array([0.3, -1.1, 0.7, 2.0, -0.4, 1.3])
        t = np.eye(4)
        k = 0
        for j in joints:
            xyz = [float(v) for v in j.find("origin").get("xyz").split()]
            r, p, y = (float(v) for v in j.find("origin").get("rpy").split())
            o = np.eye(4)
            o[:3, :3] = _rz(y) @ _ry(p) @ _rx(r)
            o[:3, 3] = xyz
            t = t @ o
            if j.get("type") == "revolute":
                rz = np.eye(4)
                rz[:3, :3] = _rz(q[k])
                t = t @ rz
                k += 1
        np.testing.assert_allclose(t, kin.fk(q, model=model), atol=1e-12)


def _rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def test_urdf_loads_in_ikpy(tmp_path):
    ikpy_chain = pytest.importorskip("ikpy.chain")
    path = tmp_path / "ur3.urdf"
    path.write_text(kin.urdf("ur3"))
    # ikpy's links: its own origin link, then one per URDF joint (6 revolute, 2 fixed).
    mask = [False] + [True] * 6 + [False, False]
    chain = ikpy_chain.Chain.from_urdf_file(
        str(path), base_elements=["base"], active_links_mask=mask, name="ur3"
    )
    q = np.array([0.3, -1.1, 0.7, 2.0, -0.4, 1.3])
    n = len(chain.links)
    full = np.zeros(n)
    active = [i for i, link in enumerate(chain.links) if link.joint_type == "revolute"]
    assert len(active) == 6
    full[active] = q
    np.testing.assert_allclose(chain.forward_kinematics(full), kin.fk(q), atol=1e-9)


@pytest.mark.parametrize("k", [0, 1, 2])
def test_hand_to_target_overflow_names_the_joint(k):
    """Finite joints near 1e308 that overflow once scaled and moved into Base: a ValueError
    naming the joint (it used to be a target holding inf)."""
    pts = [[0.0, 0.0, 0.0], [0.02, 0.08, 0.0], [0.0, 0.09, 0.01]]
    pts[k] = [1e308, 1e308, 1e308]
    name = ("wrist", "index_proximal", "middle_proximal")[k]
    for cal in ({"scale": 10.0}, {"translation": [1.7e308, 1.7e308, 1.7e308]}):
        with pytest.raises(ValueError, match=rf"^overflow: {name} is too large"):
            kin.hand_to_target(*pts, calibration=cal)
        t, ok = kin.hand_to_target_batch(*[np.array([p]) for p in pts], calibration=cal)
        assert not ok[0] and np.all(np.isfinite(t))
    # the same joints with the default calibration stay finite: a finite target
    with np.errstate(all="ignore"):
        try:
            t = kin.hand_to_target(*pts)
        except ValueError as e:  # collinear once huge: a degenerate hand, also a clear error
            assert "degenerate hand" in str(e)
        else:
            assert np.all(np.isfinite(t))


@settings(max_examples=300, deadline=None)
@given(
    arrays(np.float64, (3, 3), elements=st.floats(allow_nan=False, allow_infinity=False)),
    st.sampled_from(["left", "right"]),
)
def test_hand_to_target_any_finite_input(pts, hand):
    try:
        t = kin.hand_to_target(pts[0], pts[1], pts[2], handedness=hand)
    except ValueError:
        return
    r = t[:3, :3]
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-9)
    assert abs(np.linalg.det(r) - 1.0) < 1e-9
    assert np.all(np.isfinite(t))
