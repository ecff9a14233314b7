"""Damaged demos through the real CLI and the Python API: ``mimicrete inspect`` checks every
chunk's CRC and names the damaged ones (exit 1); salvage recovers every intact chunk wherever the
damage is, and the salvaged file loads with the lost steps declared. The expected chunk contents
come from the official ``mcap`` reader on the undamaged file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import mimicrete as mc
from _cli_run import run_cli

OBS, ACT, N = 12, 7, 80


def _write(path: Path) -> None:
    meta = {"episode": 3, "task": "suction", "robot_model": "ur3", "control_dt": 0.04}
    w = mc.demos.DemoWriter(str(path), meta, chunk_size=4096, flush_every_steps=6)
    for i in range(N):
        t = 0.04 * i
        rng = np.random.default_rng(i)
        obs = rng.standard_normal(OBS).astype(np.float32)
        act = rng.uniform(-1, 1, ACT).astype(np.float32)
        q = [0.01 * i, -1.2, 1.0, -0.5, -1.57, 0.0]
        pose = [0, 0, 0, 0, 0, 0, 1]
        w.write_step(i, t, obs, act, 0.0, i == N - 1, False, "hold", q, pose, pose, [])
    w.finish(True)


def _chunks(path: Path) -> list[dict]:
    """Offset, end and messages (topic, log time, data) of every chunk, by the official reader."""
    import io

    from mcap.reader import make_reader
    from mcap.records import Chunk, Message
    from mcap.stream_reader import StreamReader, breakup_chunk

    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    topics = {cid: ch.topic for cid, ch in summary.channels.items()}
    records = StreamReader(io.BytesIO(path.read_bytes()), emit_chunks=True).records
    contents = [
        [
            (topics[r.channel_id], r.log_time, bytes(r.data))
            for r in breakup_chunk(c, validate_crc=True)
            if isinstance(r, Message)
        ]
        for c in records
        if isinstance(c, Chunk)
    ]
    index = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(index) == len(contents)
    return [
        {"offset": ci.chunk_start_offset, "end": ci.chunk_start_offset + ci.chunk_length, "msgs": m}
        for ci, m in zip(index, contents, strict=True)
    ]


def _flip_in(data: bytes, chunk: dict) -> bytes:
    b = bytearray(data)
    b[(chunk["offset"] + chunk["end"]) // 2] ^= 0x08
    return bytes(b)


@pytest.fixture()
def demo(tmp_path: Path) -> Path:
    p = tmp_path / "ep.mcap"
    _write(p)
    return p


def test_inspect_verifies_by_default_and_names_the_damaged_chunk(demo: Path, tmp_path: Path):
    chunks = _chunks(demo)
    assert len(chunks) >= 8
    r = run_cli("inspect", str(demo))
    assert r.returncode == 0, r.stdout + r.stderr
    assert f"integrity: OK ({len(chunks)} chunks, every CRC checked)" in r.stdout
    for k in (0, len(chunks) // 2, len(chunks) - 1):
        bad = tmp_path / f"bad{k}.mcap"
        bad.write_bytes(_flip_in(demo.read_bytes(), chunks[k]))
        lost = len(chunks[k]["msgs"])
        if k < len(chunks) - 1:
            r = run_cli("inspect", str(bad))
            assert r.returncode == 1, r.stdout + r.stderr
            assert (
                f"integrity: DAMAGED (1 of {len(chunks)} chunks damaged, {lost} messages lost)"
                in r.stdout
            )
            assert f"chunk {k} at byte {chunks[k]['offset']}: " in r.stdout
            assert "salvage_to" in r.stdout
            continue
        # The JSON report says the same.
        r = run_cli("inspect", "--json", str(bad))
        assert r.returncode == 1
        info = json.loads(r.stdout)
        damaged = [c for c in info["integrity"]["chunks"] if c["error"] is not None]
        assert [(c["index"], c["offset"], c["messages"]) for c in damaged] == [
            (k, chunks[k]["offset"], lost)
        ]
        assert info["steps"] == N  # the summary itself is intact
    # --no-verify reads only the summary, as before.
    r = run_cli("inspect", "--no-verify", str(tmp_path / "bad0.mcap"))
    assert r.returncode == 0 and "integrity" not in r.stdout


def test_inspect_of_a_cut_file_reports_it(demo: Path, tmp_path: Path):
    cut = tmp_path / "cut.mcap"
    data = demo.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    r = run_cli("inspect", str(cut))
    assert r.returncode == 1
    assert "no footer: the file is cut or was never finished" in r.stdout
    assert "salvage_to" in r.stdout


def _steps(msgs) -> list[int]:
    return [json.loads(d)["step"] for topic, _, d in msgs if topic == "/demo/step"]


@pytest.mark.parametrize("which", ["first", "middle"])
def test_salvage_recovers_every_other_chunk_and_the_result_loads(
    demo: Path, tmp_path: Path, which: str
):
    chunks = _chunks(demo)
    k = 0 if which == "first" else len(chunks) // 2
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(_flip_in(demo.read_bytes(), chunks[k]))
    with pytest.raises(mc.LogFormatError, match="salvage"):
        mc.demos.load(bad)
    msgs, report = mc.demos.salvage(bad)
    expected = [m for j, c in enumerate(chunks) if j != k for m in c["msgs"]]
    assert [(m["topic"], m["log_time"], m["data"]) for m in msgs] == expected
    assert (report["chunks_ok"], report["chunks_lost"]) == (len(chunks) - 1, 1)
    assert [c["index"] for c in report["lost_chunks"]] == [k]
    fixed = tmp_path / "fixed.mcap"
    mc.demos.salvage_to(bad, fixed)
    d = mc.demos.load(fixed)
    whole = mc.demos.read(demo)
    kept = _steps(expected)
    lost = _steps(chunks[k]["msgs"])
    # Chunk 0 holds the schemas and channels (and here no step): before, losing it lost everything.
    assert lost or k == 0, "a middle chunk holds steps"
    assert len(d) == len(kept) == N - len(lost)
    assert len(msgs) == sum(len(c["msgs"]) for c in chunks) - len(chunks[k]["msgs"]) > 0
    np.testing.assert_array_equal(d.obs, whole["obs"][kept])
    np.testing.assert_array_equal(d.actions, whole["actions"][kept])
    assert d.metas[0]["salvage.step_gaps"] == (f"{lost[0]}..{lost[-1] + 1}" if lost else "")
    assert d.metas[0]["task"] == "suction"
    # The row before the gap is marked truncated (none before a leading gap); the last row keeps
    # its own flag.
    truncated_rows = np.flatnonzero(d.truncated).tolist()
    assert truncated_rows == ([lost[0] - 1] if lost and lost[0] > 0 else [])
    # The salvaged file is healthy.
    r = run_cli("inspect", str(fixed))
    assert r.returncode == 0, r.stdout
    assert "salvage:" in r.stdout and "step_gaps" in r.stdout
