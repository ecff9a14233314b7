"""Every way the live server ends keeps the episode being recorded (issue 23, part 4), and the
live demos and hand logs say what docs/formats.md §3 says (part 6).

Ctrl-C (SIGINT), ``kill`` (SIGTERM) and a closed terminal (SIGHUP) go to the real
``mimicrete teleop`` in a subprocess while a scripted client over the documented protocol
records: the server exits 0 (documented: everything recorded is on disk), the demo is a finished
``TASK_NNNN.mcap.partial`` that the official ``mcap`` reader opens with CRCs checked, its
``episode`` record says ``result`` ``interrupted`` and ``finished`` false and names the hand log
(relative, with its hash), and the hand log has every frame the client sent."""

from __future__ import annotations

import asyncio
import hashlib
import json
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import aiohttp
import numpy as np
import pytest
from aiohttp.test_utils import TestClient, TestServer
from mcap.reader import make_reader

from mimicrete.hands import model as hm
from mimicrete.hands.layouts import to_layout
from mimicrete.teleop import convert as cv
from mimicrete.teleop.live import Live
from mimicrete.teleop.protocol import pack_frame
from mimicrete.teleop.server import TeleopServer

FRAMES = 45  # sent while recording: ~0.5 s of a 90 Hz stream, 12 control steps
DOCS = Path(__file__).resolve().parents[2] / "docs" / "formats.md"


def _hand(k: int) -> np.ndarray:
    """A right hand (WebXR joints, metres, XR ``local`` space) in front of a standing user,
    drifting a little from frame to frame."""
    j = hm.hand_joints(hm.GESTURE_SHAPES["opening"], np.eye(3), np.zeros(3), handedness="right")
    return to_layout(j, "webxr") + np.array([0.1 + 0.001 * k, 1.0, -0.4])


def _t(k: int) -> float:
    return 5.0 + k / 90.0


async def _recv(ws, kind: str) -> dict:
    """The next message of type ``kind``, within 30 s (one deadline in all: the server's pings
    every 10 s would restart a per-message timeout)."""
    async with asyncio.timeout(30):
        while True:
            msg = await ws.receive_json()
            if msg["type"] == kind:
                return msg


async def _record(ws, frames: int, seq0: int = 0) -> list[dict]:
    """Start an episode and send ``frames`` hand frames, each answered by a state."""
    await ws.send_json({"type": "control", "action": "start"})
    started = await _recv(ws, "episode")
    assert started["event"] == "started"
    states = []
    for k in range(frames):
        await ws.send_bytes(pack_frame(seq0 + k, _t(k), 1000.0 + k, _hand(k)))
        states.append(await _recv(ws, "state"))
    return states


def _episode_record(path: Path) -> dict[str, str]:
    """The demo's ``episode`` metadata record, read with the official reader (every message
    read too, CRCs checked)."""
    with open(path, "rb") as f:
        r = make_reader(f, validate_crcs=True)
        steps = sum(1 for _ in r.iter_messages(topics=["/demo/step"]))
        assert steps > 0
        records = {m.name: dict(m.metadata) for m in r.iter_metadata()}
    return records["episode"]


def _check_source(rec: dict[str, str], demo: Path, hand: Path) -> None:
    assert rec["source_handlog"] == hand.name  # beside the demo: its bare name
    assert rec["source_handlog_sha256"] == hashlib.sha256(hand.read_bytes()).hexdigest()


# ----------------------------------------------------------------------------------------------
# part 4: the real CLI, one signal each
# ----------------------------------------------------------------------------------------------


def _default_signals() -> None:
    """In the child: SIGINT, SIGTERM and SIGHUP at their defaults, as a terminal gives them. A
    shell's background job (or nohup) starts with SIGINT / SIGHUP ignored, and a command that
    inherits an ignored signal rightly keeps ignoring it; the test would then wait forever."""
    for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(s, signal.SIG_DFL)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def _drive_then_signal(proc: subprocess.Popen, port: int, sig: int) -> list[dict]:
    url = f"http://127.0.0.1:{port}/ws"
    async with aiohttp.ClientSession() as http:
        deadline = time.monotonic() + 60
        while True:  # the command imports for a few seconds before it listens
            try:
                ws = await http.ws_connect(url)
                break
            except aiohttp.ClientConnectionError:
                assert proc.poll() is None, "mimicrete teleop exited before it listened"
                assert time.monotonic() < deadline, "mimicrete teleop did not listen"
                await asyncio.sleep(0.1)
        await ws.send_json({"type": "hello", "protocol": 1, "role": "driver", "client": "test"})
        assert (await _recv(ws, "hello"))["role"] == "driver"
        states = await _record(ws, FRAMES)
        proc.send_signal(sig)
        async for _ in ws:  # the server closes the socket once it has saved
            pass
    return states


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=str)
def test_a_signal_mid_episode_keeps_the_demo_and_the_whole_handlog(tmp_path, sig):
    out, port = tmp_path / "out", _free_port()
    cmd = [sys.executable, "-m", "mimicrete", "teleop", "--task", "suction", "--out", str(out)]
    with open(tmp_path / "stdout", "wb") as so, open(tmp_path / "stderr", "wb") as se:
        proc = subprocess.Popen(
            [*cmd, "--port", str(port)], stdout=so, stderr=se, preexec_fn=_default_signals
        )
        try:
            states = asyncio.run(asyncio.wait_for(_drive_then_signal(proc, port, sig), 180))
            code = proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    err = (tmp_path / "stderr").read_text()
    assert code == 0, (code, err)
    assert all(s["recording"] for s in states)
    demo, hand = out / "suction_0000.mcap.partial", out / "suction_0000.handlog.jsonl"
    assert sorted(p.name for p in out.iterdir() if p.name.startswith("suction_")) == [
        hand.name,
        demo.name,
    ]
    rec = _episode_record(demo)
    assert json.loads(rec["result"]) == "interrupted" and json.loads(rec["finished"]) is False
    _check_source(rec, demo, hand)
    log = cv.load_log(hand)
    np.testing.assert_array_equal(log.t, [_t(k) for k in range(FRAMES)])
    np.testing.assert_allclose(log.joints[-1], _hand(FRAMES - 1), atol=1e-6)  # f32 on the wire
    saved = (tmp_path / "stdout").read_text()
    assert "'result': 'interrupted'" in saved and "'finished': False" in saved
    assert f"stopped by {signal.Signals(sig).name}" in err and "Traceback" not in err


# ----------------------------------------------------------------------------------------------
# part 6: the live server says what the docs say (in process, aiohttp's test server)
# ----------------------------------------------------------------------------------------------


def _serve(live: Live, body):
    async def go():
        client = TestClient(TestServer(TeleopServer(live).app()))
        await client.start_server()
        try:
            return await body(client)
        finally:
            await client.close()

    return asyncio.run(go())


async def _driver(client):
    ws = await client.ws_connect("/ws")
    await ws.send_json({"type": "hello", "protocol": 1, "role": "driver", "client": "test"})
    assert (await _recv(ws, "hello"))["role"] == "driver"
    return ws


def test_a_frame_whose_time_goes_back_is_dropped_counted_and_not_logged(tmp_path):
    live = Live("suction", tmp_path / "out")

    async def go(client):
        ws = await _driver(client)
        await _record(ws, 10)
        await ws.send_bytes(pack_frame(10, _t(3), 0.0, _hand(3)))  # back in time: no answer
        await ws.send_bytes(pack_frame(11, _t(10), 0.0, _hand(10)))
        after = await _recv(ws, "state")
        await ws.send_json({"type": "control", "action": "stop"})
        await _recv(ws, "episode")
        await ws.close()
        return after

    after = _serve(live, go)
    assert after["seq"] == 11 and after["dropped"]["backwards"] == 1
    saved = live.last_saved
    log = cv.load_log(saved["handlog"])
    np.testing.assert_array_equal(log.t, [_t(k) for k in range(11)])


def test_live_demo_and_handlog_metadata_follow_the_docs_and_convert_alike(tmp_path):
    live = Live("suction", tmp_path / "out")

    async def go(client):
        ws = await _driver(client)
        await _record(ws, FRAMES)
        await ws.send_json({"type": "control", "action": "stop"})
        await _recv(ws, "episode")
        await ws.close()

    _serve(live, go)
    saved = live.last_saved
    demo, hand = Path(saved["demo"]), Path(saved["handlog"])
    assert demo.name == "suction_0000.mcap" and saved["result"] == "stopped"
    with open(demo, "rb") as f:
        records = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}
    rec = records["episode"]
    _check_source(rec, demo, hand)
    assert json.loads(rec["finished"]) is True and json.loads(rec["result"]) == "stopped"
    # no second, absolute name of the hand log among the caller's keys
    assert not any(str(hand) in v for v in records["episode_start"].values())
    # the hand's space as the formats write it (§1: webxr is read as openxr), in both files
    log = cv.load_log(hand)
    assert log.header["layout"] == "webxr" and log.header["space"] == "openxr"
    assert rec["hand_layout"] == "webxr" and rec["hand_space"] == "openxr"
    # `mimicrete convert` names its source the same way: relative to the demo, hashed
    again = cv.convert_log(hand, "suction", tmp_path / "conv" / "again.mcap")
    with open(again.out, "rb") as f:
        conv = {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}["episode"]
    assert conv["source_handlog"] == "../out/suction_0000.handlog.jsonl"
    assert conv["source_handlog_sha256"] == rec["source_handlog_sha256"]


def test_a_second_driver_gets_its_hello_before_the_error(tmp_path):
    live = Live("suction", tmp_path / "out")

    async def go(client):
        await _driver(client)
        b = await client.ws_connect("/ws")
        await b.send_json({"type": "hello", "protocol": 1, "role": "driver"})
        return [await b.receive_json(timeout=10) for _ in range(2)]

    first, second = _serve(live, go)
    assert first["type"] == "hello" and first["role"] == "viewer"
    assert second["type"] == "error"


def test_every_result_the_server_gives_is_documented():
    text = DOCS.read_text()
    listed = re.search(r"`last_result` \((.*?)\), `dropped`", text, re.S)
    assert listed is not None
    names = set(re.findall(r"`([^`]+)`", listed.group(1)))
    # Live.stop: the tasks' successes, fell, time limit, stopped; the server: disconnected,
    # interrupted; Live.discard: discarded
    from mimicrete import tasks

    given = {tasks.get(t).success for t in ("suction", "grip", "screw")}
    given |= {"fell", "time limit", "stopped", "disconnected", "interrupted", "discarded"}
    assert given <= names, given - names
    assert "backwards" in text[text.index("`dropped` (") :][:200]
