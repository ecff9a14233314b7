"""Exceptions from the Rust core carry the Rust errors' fields (``IkError.reason`` / ``.iters`` /
``.pos_residual_m`` / ``.rot_residual_rad``, ``LogFormatError.file`` / ``.line`` / ``.reason``,
``SimError.reason``, ``ActionShapeError.expected`` / ``.got``, ``IoError.errno`` /
``.filename``), on real failing inputs; ``str(e)`` keeps the native message. Every exception
class of the package is a MimicreteError."""

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


# ---------------------------------------------------------------------------------------------
# One exception tree (issue 25 §2): the simulator's refusals, the OS's errors and every exception
# class the Python package defines are MimicreteErrors, and stay the built-in class callers catch.


def test_action_shape_error_carries_the_shapes():
    env = _native.SimEnv("TileSuction", 0)
    env.reset(0)
    with pytest.raises(mc.ActionShapeError) as ei:
        env.step(np.zeros(6, np.float32))
    e = ei.value
    assert (e.expected, e.got, e.task) == ((7,), (6,), "TileSuction")
    assert isinstance(e, ValueError) and isinstance(e, mc.SimError)
    assert isinstance(e, mc.SimInputError) and isinstance(e, mc.MimicreteError)
    assert str(e) == e.reason == "action must have shape (7,), got (6,)"
    venv = _native.SimVecEnv("suction", 2, num_threads=1)
    venv.reset(0)
    with pytest.raises(mc.ActionShapeError) as ei:
        venv.step(np.zeros((2, 6), np.float32))
    assert (ei.value.expected, ei.value.got, ei.value.task) == ((2, 7), (2, 6), "TileSuction")
    # The class attributes exist (None) for a user-constructed one.
    plain = mc.ActionShapeError("free text")
    assert (plain.expected, plain.got, plain.task) == (None, None, None)


def test_the_simulators_other_refusals_are_sim_input_errors():
    with pytest.raises(mc.SimInputError) as ei:
        _native.SimEnv("nope", 0)
    assert isinstance(ei.value, ValueError) and 'unknown task "nope"' in ei.value.reason
    env = _native.SimEnv("TileSuction", 0)
    env.reset(0)
    with pytest.raises(mc.SimInputError, match="not finite"):
        env.step(np.array([0, 0, 0, np.nan, 0, 0, 0], np.float32))


def test_io_errors_keep_errno_filename_and_their_os_error_class(tmp_path: Path):
    import errno

    missing = tmp_path / "absent.mcap"
    with pytest.raises(FileNotFoundError) as ei:
        mc.demos.read(missing)
    e = ei.value
    assert isinstance(e, mc.IoError) and isinstance(e, mc.MimicreteError)
    assert (e.errno, e.filename, e.strerror) == (
        errno.ENOENT,
        str(missing),
        "No such file or directory",
    )
    # A file where a directory of demos should be: NotADirectoryError, ENOTDIR.
    f = tmp_path / "plain.txt"
    f.write_text("x")
    with pytest.raises(NotADirectoryError) as ei:
        _native.demo_files(f)
    assert isinstance(ei.value, mc.IoError)
    assert (ei.value.errno, ei.value.filename) == (errno.ENOTDIR, str(f))
    # One class per errno kind, reused.
    with pytest.raises(FileNotFoundError) as again:
        _native.demo_read(tmp_path / "other.mcap")
    assert type(again.value) is type(e)


def test_a_bad_pose_is_refused_with_its_reason(tmp_path: Path):
    env = _native.SimEnv("TileSuction", 0)
    good = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    step = dict(
        step=0,
        t=0.0,
        obs=np.zeros(env.obs_dim, np.float32),
        action=np.zeros(env.act_dim, np.float32),
        reward=0.0,
        terminated=False,
        truncated=False,
        gesture="none",
        joints=[0.0] * 6,
        tile_pose=good,
    )
    w = _native.DemoWriter(tmp_path / "d.mcap", {"task": "TileSuction"})
    try:
        # Formerly any value the JSON conversion refused became null, and the error only said
        # the pose must be 7 numbers: the NaN or the foreign object went unnamed.
        with pytest.raises(ValueError, match=r"^ee_pose: nan is not a finite number"):
            w.write_step(ee_pose=[0.0, 0.0, float("nan"), 0.0, 0.0, 0.0, 1.0], **step)
        with pytest.raises(ValueError, match=r"^ee_pose: object is not JSON data"):
            w.write_step(ee_pose=object(), **step)
        with pytest.raises(ValueError, match=r"ee_pose must be \[x, y, z, qx, qy, qz, qw\]"):
            w.write_step(ee_pose=good[:6], **step)
        assert w.steps == 0
        w.write_step(ee_pose=good, **step)
        assert w.steps == 1
    finally:
        w.abandon()


def _python_exception_classes() -> list[type[BaseException]]:
    """Every exception class defined in the package's Python sources (found by parsing them; only
    the modules that define a class are imported)."""
    import ast
    import importlib

    root = Path(mc.__file__).resolve().parent
    found = []
    for src in sorted(root.rglob("*.py")):
        names = [n.name for n in ast.parse(src.read_text()).body if isinstance(n, ast.ClassDef)]
        if not names:
            continue
        rel = src.relative_to(root.parent).with_suffix("")
        mod_name = ".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)
        try:
            mod = importlib.import_module(mod_name)
        except ImportError:  # an optional dependency (playwright, ray, ...) not installed
            continue
        for name in names:
            c = getattr(mod, name, None)
            if isinstance(c, type) and issubclass(c, BaseException) and c.__module__ == mod_name:
                found.append(c)
    return found


def test_every_exception_class_of_the_package_is_a_mimicrete_error():
    classes = _python_exception_classes()
    assert len(classes) >= 19
    outside = [
        f"{c.__module__}.{c.__qualname__}" for c in classes if not issubclass(c, mc.MimicreteError)
    ]
    assert not outside, outside
    # One name, one class (formerly learn's DemoError shared its name with demo-log's).
    names = [c.__name__ for c in classes] + [
        n for n in _native.__all__ if isinstance(getattr(_native, n), type)
    ]
    assert sorted(set(names)) == sorted(names)
    assert "DemoError" not in names
    # Callers catch these as the built-in classes too.
    from mimicrete import learn, safe_io
    from mimicrete.gestures import captured

    assert issubclass(learn.DemoDataError, ValueError)
    assert issubclass(learn.ConfigError, ValueError)
    assert issubclass(safe_io.WriteError, OSError)
    assert issubclass(safe_io.LockBusyError, RuntimeError)
    assert issubclass(captured.CapturedDataMissing, FileNotFoundError)
    assert issubclass(learn.NonFiniteLossError, RuntimeError)
