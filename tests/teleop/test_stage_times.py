"""Per-stage latency of a live recording (issue 23, part 5): every control step's hand frame is
timed at capture, send, server receipt, state sent and the page's receipt of that state (from the
client's ``ack``), recorded on ``/teleop/stage_times``; ``mimicrete inspect`` prints p50 / p99."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
from mcap.reader import make_reader

from mimicrete import demos
from mimicrete.teleop import convert as cv
from mimicrete.teleop.live import Live
from mimicrete.teleop.protocol import pack_frame
from mimicrete.teleop.server import TeleopServer

from .test_server import _driver, _log, _serve

SEND_MS = 0.7  # the client sends each frame this long after its capture


def _page_ms(seq: int) -> float:
    """When the scripted client 'received' the state of frame seq: 3–7 ms after sending it."""
    return 3.0 + seq % 5


def _unacked(seq: int) -> bool:
    return seq % 10 == 7  # a tenth of the states are never acknowledged


def _record(tmp_path):
    log = _log(tmp_path)
    seed = int(log.header["episode_seed"])
    live = Live("suction", tmp_path / "out", calibration=cv.calibration_of(log), seed=seed)

    async def go(client):
        ws, _ = await _driver(client)
        await ws.send_json({"type": "control", "action": "start"})
        await ws.send_json({"type": "ack", "states": "soon"})  # malformed: dropped, counted
        acks: list[list[float]] = []
        last = None
        for k in range(len(log.t)):
            cap = float(log.t[k]) * 1000.0
            right = log.joints[k] if log.tracked[k] else None
            await ws.send_bytes(pack_frame(k, float(log.t[k]), cap + SEND_MS, right))
            while (msg := await ws.receive_json(timeout=10))["type"] != "state":
                pass
            last = msg
            if not _unacked(k):
                acks.append([k, cap + SEND_MS + _page_ms(k)])
            if len(acks) == 16:
                await ws.send_json({"type": "ack", "states": acks})
                acks = []
            if not msg["recording"]:
                break
        await ws.close()
        return last

    server = TeleopServer(live)
    last = _serve(server, go)
    assert last["last_result"] == "installed", last
    return log, live, server


def _records(path, topic=demos.STAGE_TIMES_TOPIC) -> list[dict]:
    with open(path, "rb") as f:
        return [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=[topic])]


def test_each_control_step_records_its_frame_stages(tmp_path):
    log, live, server = _record(tmp_path)
    assert server.stats.dropped["malformed"] == 1
    saved = live.last_saved
    d = demos.load(saved["demo"])
    recs = _records(saved["demo"])
    step_t = {r["step"]: r["t"] for r in _records(saved["demo"], demos.STEP_TOPIC)}
    steps = len(d.actions)
    assert sorted(r["step"] for r in recs) == list(range(steps))  # one per control step
    last_seq = max(r["seq"] for r in recs)
    for r in recs:
        k = r["seq"]
        # the frame's own times, as the client sent them
        assert r["capture_ms"] == float(log.t[k]) * 1000.0
        assert r["sent_ms"] == r["capture_ms"] + SEND_MS
        # a step runs at a control tick the frame's time has reached
        assert step_t[r["step"]] <= log.t[k] + 1e-9
        if k == last_seq:  # the episode ended on this frame, before its state went out
            assert r["state_sent_ms"] is None and r["page_recv_ms"] is None
            continue
        assert r["state_sent_ms"] >= r["server_recv_ms"]
        if _unacked(k):
            assert r["page_recv_ms"] is None
        elif r["page_recv_ms"] is not None:
            assert r["page_recv_ms"] == r["sent_ms"] + _page_ms(k)
    acked = [r for r in recs if r["page_recv_ms"] is not None]
    # all acknowledged states but the last batch (unsent when the episode ended) are known
    assert len(acked) >= len([r for r in recs if not _unacked(r["seq"])]) - 16
    # inspect's p50 / p99 are the stages of exactly these records
    stages = demos.inspect(saved["demo"])["stages"]
    rtt = [_page_ms(r["seq"]) for r in acked]
    want = stages["round trip: sent -> state received"]
    assert want["n"] == len(acked)
    assert np.isclose(want["p50"], np.percentile(rtt, 50), atol=1e-9)
    assert np.isclose(want["p99"], np.percentile(rtt, 99), atol=1e-9)
    age = stages["hand age when its state arrived"]
    assert np.isclose(age["p50"], np.percentile([x + SEND_MS for x in rtt], 50), atol=1e-9)
    assert np.isclose(stages["page: capture -> sent"]["p50"], SEND_MS)
    assert stages["page: capture -> sent"]["n"] == steps


def test_inspect_prints_the_stages_and_offline_demos_have_none(tmp_path):
    _, live, _ = _record(tmp_path)
    demo = live.last_saved["demo"]
    out = subprocess.run(
        [sys.executable, "-m", "mimicrete", "inspect", demo],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "stage times (ms" in out
    line = next(x for x in out.splitlines() if "round trip: sent -> state received" in x)
    p50, p99, n = line.split()[-3:]
    stages = demos.inspect(demo)["stages"]["round trip: sent -> state received"]
    assert (float(p50), float(p99), int(n)) == (
        round(stages["p50"], 2),
        round(stages["p99"], 2),
        stages["n"],
    )
    # the converted hand log: the same steps, no live stages
    again = cv.convert_log(live.last_saved["handlog"], "suction", tmp_path / "again")
    assert demos.inspect(again.out)["stages"] == {}
    out = subprocess.run(
        [sys.executable, "-m", "mimicrete", "inspect", str(again.out)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert "stage times" not in out


def test_a_damaged_live_demo_is_still_inspected(tmp_path):
    """A flipped byte in a chunk of a live demo: inspect reports the damage (exit 1), the stage
    times it could not read say so, and nothing raises."""
    _, live, _ = _record(tmp_path)
    data = bytearray(open(live.last_saved["demo"], "rb").read())
    data[len(data) // 2] ^= 0x55
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(bytes(data))
    r = subprocess.run(
        [sys.executable, "-m", "mimicrete", "inspect", str(bad)],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 1, r.stdout + r.stderr
    assert "integrity: DAMAGED" in r.stdout and "Traceback" not in r.stderr
