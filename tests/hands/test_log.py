"""Hand logs through the Python helpers: numpy round trip, error messages (file:line: reason),
lenient reports, and logs written with Python's own json module."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mimicrete as mc

HEADER = {
    "format": "mimicrete.handlog",
    "version": 1,
    "layout": "webxr",
    "space": "unity",
    "handedness": "left",
    "units": "m",
}


def _write_lines(path: Path, header: dict, frames: list, newline_at_end: bool = True) -> Path:
    text = "\n".join([json.dumps(header)] + [json.dumps(f) for f in frames])
    path.write_text(text + ("\n" if newline_at_end else ""))
    return path


def _frame(t: float, n: int = 25, tracked: bool = True, v: float = 0.1) -> dict:
    return {"t": t, "tracked": tracked, "joints": [[v, v + 1.0, -v]] * n}


def test_round_trip_numpy(tmp_path: Path):
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0, 0.02, 50))
    tracked = rng.uniform(size=50) > 0.2
    joints = rng.standard_normal((50, 26, 3))
    quats = rng.standard_normal((50, 26, 4))
    header = {
        "layout": "openxr",
        "space": "robot_base",
        "handedness": "right",
        "task": "suction",
        "episode_seed": 12,
        "source": "pytest",
        "extra": {"fps": 72, "ok": [1, 2]},
    }
    p = tmp_path / "h.jsonl"
    mc.hands.write(p, header, t, tracked, joints, quats)
    log = mc.hands.parse(p)
    np.testing.assert_array_equal(log.t, t)  # bit-exact
    np.testing.assert_array_equal(log.tracked, tracked)
    np.testing.assert_array_equal(log.joints, joints)
    np.testing.assert_array_equal(log.orientations, quats)
    assert log.header["layout"] == "openxr" and log.header["joint_count"] == 26
    assert log.header["episode_seed"] == 12 and log.header["extra"] == {"fps": 72, "ok": [1, 2]}
    assert log.report["kept"] == 50
    lenient = mc.hands.parse(p, mode="lenient")
    assert len(lenient) == int(tracked.sum())
    assert lenient.report["untracked_skipped"] == int((~tracked).sum())
    assert [ln for ln, _ in lenient.report["skipped"]] == [i + 2 for i in np.flatnonzero(~tracked)]


@pytest.mark.parametrize(
    ("frames", "header", "newline", "line", "reason"),
    [
        (
            [_frame(0.0), _frame(0.1, n=24)],
            HEADER,
            True,
            3,
            "wrong joint count: 24 joints, layout webxr has 25",
        ),
        (
            [_frame(0.0), {**_frame(0.1), "joints": [[float("nan"), 0, 0]] * 25}],
            HEADER,
            True,
            3,
            "non-finite value (NaN) in joint 0 coordinate x",
        ),
        (
            [_frame(0.0), _frame(float("inf"))],
            HEADER,
            True,
            3,
            'non-finite value (Infinity) in "t"',
        ),
        ([_frame(0.5), _frame(0.2)], HEADER, True, 3, "time goes backwards: t=0.2 after t=0.5"),
        (
            [_frame(0.0)],
            {**HEADER, "layout": "kinect"},
            True,
            1,
            'header: unknown layout "kinect" (known: openxr, webxr, meta_ovr, mediapipe)',
        ),
        (
            [_frame(0.0)],
            {k: v for k, v in HEADER.items() if k != "handedness"},
            True,
            1,
            'header: missing field "handedness"',
        ),
        (
            [_frame(0.0)],
            {**HEADER, "format": "bvh"},
            True,
            1,
            'unknown format "bvh" in header (expected "mimicrete.handlog")',
        ),
    ],
)
def test_error_messages(tmp_path: Path, frames, header, newline, line, reason):
    p = _write_lines(tmp_path / "bad.jsonl", header, frames, newline)
    with pytest.raises(mc.LogFormatError) as e:
        mc.hands.parse(p)
    assert str(e.value) == f"{p}:{line}: {reason}"
    assert isinstance(e.value, mc.MimicreteError)


def test_missing_header_and_truncated_last_line(tmp_path: Path):
    p = tmp_path / "nohdr.jsonl"
    p.write_text(json.dumps(_frame(0.0)) + "\n")
    with pytest.raises(mc.LogFormatError, match=r"nohdr.jsonl:1: missing header"):
        mc.hands.parse(p)
    p = tmp_path / "cut.jsonl"
    full = json.dumps(HEADER) + "\n" + json.dumps(_frame(0.0)) + "\n" + json.dumps(_frame(0.1))
    p.write_text(full[:-15])
    with pytest.raises(mc.LogFormatError, match=r"cut.jsonl:3: truncated last line"):
        mc.hands.parse(p)
    log = mc.hands.parse(p, mode="lenient")
    assert len(log) == 1 and log.report["invalid_skipped"] == 1
    assert log.report["skipped"][0][0] == 3


def test_nothing_half_written(tmp_path: Path):
    p = tmp_path / "h.jsonl"
    joints = np.zeros((3, 21, 3))
    joints[2, 4, 1] = np.inf
    with pytest.raises(mc.LogFormatError, match=r"h.jsonl:4: non-finite value in joint 4"):
        mc.hands.write(
            p,
            {"layout": "mediapipe", "space": "openxr", "handedness": "right"},
            np.arange(3.0),
            np.ones(3, bool),
            joints,
        )
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match=r"joints \(T, 21, 3\)"):
        mc.hands.write(
            p,
            {"layout": "mediapipe", "space": "openxr", "handedness": "right"},
            np.arange(3.0),
            np.ones(3, bool),
            np.zeros((3, 20, 3)),
        )


def test_parse_text_and_bad_mode():
    text = json.dumps(HEADER) + "\n" + json.dumps(_frame(0.0)) + "\n"
    assert len(mc.hands.parse_text(text, "mem")) == 1
    with pytest.raises(ValueError, match="strict' or 'lenient"):
        mc.hands.parse_text(text, "mem", mode="sloppy")
    with pytest.raises(mc.LogFormatError, match=r"^mem:2: "):
        mc.hands.parse_text(text.replace('"t": 0.0', '"t": "x"'), "mem")


# Coordinates within the parser's range (10 km, ``demo_log::MAX_COORD_M``): every float there,
# subnormals included, must come back bit-exactly.
finite = st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=60, deadline=None)
@given(
    dts=st.lists(st.floats(0, 10, allow_nan=False), min_size=0, max_size=8),
    vals=st.lists(finite, min_size=21 * 3, max_size=21 * 3),
    tracked=st.booleans(),
)
def test_python_json_written_logs_parse_exactly(tmp_path_factory, dts, vals, tracked):
    # Logs written by Python's json module (as a device bridge would) parse to the same floats.
    t = np.cumsum(np.array(dts, dtype=np.float64)) if dts else np.zeros(0)
    joints = np.array(vals, dtype=np.float64).reshape(21, 3)
    frames = [{"t": float(ti), "tracked": tracked, "joints": joints.tolist()} for ti in t]
    p = _write_lines(
        tmp_path_factory.mktemp("h") / "h.jsonl", {**HEADER, "layout": "mediapipe"}, frames
    )
    log = mc.hands.parse(p)
    assert len(log) == len(frames)
    if frames:
        np.testing.assert_array_equal(log.t, t)
        np.testing.assert_array_equal(log.joints, np.broadcast_to(joints, (len(frames), 21, 3)))


def test_byte_order_marks(tmp_path: Path):
    """A UTF-8 BOM at the start (Windows editors, Python's utf-8-sig) is accepted; a BOM at the
    start of a later line (two files concatenated) and a UTF-16 file are named."""
    frames = [_frame(0.0), _frame(0.01)]
    text = "\n".join([json.dumps(HEADER)] + [json.dumps(f) for f in frames]) + "\n"
    plain = tmp_path / "plain.jsonl"
    plain.write_text(text, encoding="utf-8")
    bom = tmp_path / "bom.jsonl"
    bom.write_text(text, encoding="utf-8-sig")
    assert bom.read_bytes()[:3] == b"\xef\xbb\xbf"
    a, b = mc.hands.parse(plain), mc.hands.parse(bom)
    np.testing.assert_array_equal(a.joints, b.joints)
    assert a.header == b.header and len(b) == 2
    assert len(mc.hands.parse_text("\ufeff" + text)) == 2
    cat = tmp_path / "cat.jsonl"
    cat.write_bytes(text.encode() + b"\xef\xbb\xbf" + json.dumps(_frame(0.02)).encode() + b"\n")
    with pytest.raises(
        mc.LogFormatError, match=r"cat.jsonl:4: line starts with a UTF-8 byte-order"
    ):
        mc.hands.parse(cat)
    u16 = tmp_path / "u16.jsonl"
    u16.write_text(text, encoding="utf-16")
    with pytest.raises(mc.LogFormatError, match=r"u16.jsonl:1: .*UTF-16 byte-order mark"):
        mc.hands.parse(u16)
