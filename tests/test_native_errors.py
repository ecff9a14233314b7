"""Exceptions from the Rust core carry the Rust errors' fields (``IkError.reason`` / ``.iters`` /
``.pos_residual_m`` / ``.rot_residual_rad``, ``LogFormatError.file`` / ``.line`` / ``.reason``,
``SimError.reason``), on real failing inputs; ``str(e)`` keeps the native message."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import mimicrete as mc
from mimicrete import _native, kin
from mimicrete.hands import log as handlog


def test_ik_not_converged_carries_iterations_and_residuals():
    q = np.array([0.4, -1.2, 1.0, -1.3, -1.5, 0.2])
    t = kin.fk(q)
    with pytest.raises(mc.IkError) as ei:
        kin.ik_gn(t, np.zeros(6), max_iters=1)
    e = ei.value
    assert e.reason == "did not converge"
    assert e.iters == 1
    # The residuals of one Gauss-Newton step from zero: finite, far above the tolerance, and the
    # ones the message prints (3 significant digits).
    assert isinstance(e.pos_residual_m, float) and isinstance(e.rot_residual_rad, float)
    assert 1e-3 < e.pos_residual_m < 1.0 and 1e-3 < e.rot_residual_rad < 4.0
    m = re.search(r"position residual (\S+) m, rotation residual (\S+) rad", str(e))
    assert m is not None
    assert float(m.group(1)) == pytest.approx(e.pos_residual_m, rel=5e-3)
    assert float(m.group(2)) == pytest.approx(e.rot_residual_rad, rel=5e-3)
    assert str(e).startswith("IK did not converge after 1 iterations")


def test_ik_unreachable_has_a_reason_and_no_solver_numbers():
    t = np.eye(4)
    t[0, 3] = 2.0  # 2 m from the shoulder: beyond the UR3's 0.5 m reach
    with pytest.raises(mc.IkError) as ei:
        kin.ik(t)
    e = ei.value
    assert e.reason == "farther from the shoulder than the arm's reach"
    assert (e.iters, e.pos_residual_m, e.rot_residual_rad) == (None, None, None)
    assert str(e) == f"target unreachable: {e.reason}"
    assert isinstance(e, mc.MimicreteError)


def test_handlog_error_fields(tmp_path: Path):
    header = handlog.header("mediapipe", "openxr", "right")
    frame = {"t": 0.0, "tracked": True, "joints": [[0.0, 0.0, 0.0]] * 21}
    bad = dict(frame, t=0.1, joints=[[0.0, 0.0, 0.0]] * 20)
    p = tmp_path / "bad.jsonl"
    p.write_text("\n".join(json.dumps(x) for x in (header, frame, bad)) + "\n")
    with pytest.raises(mc.LogFormatError) as ei:
        mc.hands.parse(p)
    e = ei.value
    assert (e.file, e.line) == (str(p), 3)
    assert e.reason == "wrong joint count: 20 joints, layout mediapipe has 21"
    assert str(e) == f"{e.file}:{e.line}: {e.reason}"
    with pytest.raises(mc.LogFormatError) as ei:
        mc.hands.parse_text(json.dumps(header) + "\n" + '{"t": "x"}\n', "mem")
    assert (ei.value.file, ei.value.line) == ("mem", 2)


def test_demo_file_error_has_file_and_no_line(tmp_path: Path):
    p = tmp_path / "junk.mcap"
    p.write_bytes(b"not an mcap file at all" * 4)
    with pytest.raises(mc.LogFormatError) as ei:
        mc.demos.read(p)
    e = ei.value
    assert e.file == str(p) and e.line is None
    assert e.reason and str(e) == f"{p}: {e.reason}"


def test_python_raised_log_errors_have_the_same_fields(tmp_path: Path):
    e = _native.log_format_error("x.jsonl", 2, "no frames")
    assert isinstance(e, mc.LogFormatError)
    assert (e.file, e.line, e.reason, str(e)) == ("x.jsonl", 2, "no frames", "x.jsonl:2: no frames")
    # A user-constructed one has the fields too (None).
    plain = mc.LogFormatError("free text")
    assert (plain.file, plain.line, plain.reason) == (None, None, None)
    # The converter's own check (a log with a header and no frames) uses it.
    from mimicrete.teleop import convert as cv

    p = tmp_path / "empty.jsonl"
    p.write_text(json.dumps(handlog.header("mediapipe", "openxr", "right")) + "\n")
    with pytest.raises(mc.LogFormatError) as ei:
        cv.load_log(p)
    assert (ei.value.file, ei.value.line, ei.value.reason) == (str(p), 2, "no frames")


def test_sim_error_reason():
    env = _native.SimEnv("TileSuction", 0)
    env.reset(0)
    env.set_object_pose([0.9, 0.0, 0.05], [0.0, 0.0, 0.0, 1.0])  # off the table: it falls
    for _ in range(50):
        if env.step(np.zeros(7, np.float32))[2]:
            break
    with pytest.raises(mc.SimError) as ei:
        env.step(np.zeros(7, np.float32))
    assert ei.value.reason == str(ei.value)
    assert "call reset before step" in ei.value.reason
