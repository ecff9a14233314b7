"""The live server over a real WebSocket (aiohttp's test server on loopback, no browser): a
synthetic demonstration streamed as protocol frames installs the tile, saves a demo and a hand log,
and the hand log converts offline to the same steps, actions and rewards. Bad input is dropped
and counted; a second client watches; a wrong token and a foreign origin are refused; a disconnect
mid-episode keeps what was recorded."""

from __future__ import annotations

import asyncio
import json

import numpy as np
import pytest
from aiohttp.test_utils import TestClient, TestServer

from mimicrete import demonstrator as sy
from mimicrete import demos
from mimicrete.hands.log import HandLogData
from mimicrete.teleop import convert as cv
from mimicrete.teleop.live import Live
from mimicrete.teleop.protocol import FRAME_BYTES, pack_frame
from mimicrete.teleop.server import TeleopServer


def _log(tmp_path, task="suction", seed=3):
    path = sy.synth_hands(task, 1, seed, tmp_path / "hands", layout="webxr")[0]
    return cv.load_log(path)


async def _client(server: TeleopServer) -> TestClient:
    client = TestClient(TestServer(server.app()))
    await client.start_server()
    return client


async def _hello(ws, role="driver"):
    await ws.send_json({"type": "hello", "protocol": 1, "role": role, "client": "test"})
    while True:
        msg = await ws.receive_json(timeout=10)
        if msg["type"] == "hello":
            return msg


async def _stream(ws, log, seq0=0, until=None):
    """Send the log's frames one at a time, each answered by a state; returns the states."""
    states = []
    for k in range(len(log.t)):
        right = log.joints[k] if log.tracked[k] else None
        await ws.send_bytes(pack_frame(seq0 + k, float(log.t[k]), 1000.0 + k, right))
        while True:
            msg = await ws.receive_json(timeout=10)
            if msg["type"] == "state":
                break
        assert msg["seq"] == seq0 + k and msg["sent_ms"] == 1000.0 + k
        states.append(msg)
        if until is not None and until(msg):
            break
    return states


def _run(coro):
    return asyncio.run(coro)


def _suction(tmp_path) -> tuple[HandLogData, Live]:
    """A synthetic suction hand log and a live session calibrated and seeded for it."""
    log = _log(tmp_path)
    return log, Live("suction", tmp_path / "out", calibration=cv.calibration_of(log), seed=3)


def _serve(server: TeleopServer, body):
    """``await body(client)`` against ``server`` on a loopback test client, closed afterwards."""

    async def go():
        client = await _client(server)
        try:
            return await body(client)
        finally:
            await client.close()

    return _run(go())


async def _driver(client: TestClient):
    """A WebSocket that has said hello as the driver, and the server's hello."""
    ws = await client.ws_connect("/ws")
    return ws, await _hello(ws)


@pytest.mark.parametrize("task", ["suction", "grip", "screw"])
def test_live_episode_installs_and_its_handlog_converts_to_the_same_demo(tmp_path, task):
    log = _log(tmp_path, task)
    calib = cv.calibration_of(log)
    live = Live(task, tmp_path / "out", calibration=calib, seed=int(log.header["episode_seed"]))

    async def go(client):
        ws, hello = await _driver(client)
        assert hello["role"] == "driver" and hello["task"] == task
        assert {e["frame_id"] for e in hello["scene"]} - {"base"} <= set(hello["frames"])
        assert len(hello["view_from_base"]) == 16
        await ws.send_json({"type": "control", "action": "start"})
        states = await _stream(ws, log, until=lambda m: not m["recording"])
        await ws.close()
        return states

    states = _serve(TeleopServer(live), go)
    assert states[0]["recording"] and states[-1]["last_result"] == live.task.success
    saved = live.last_saved
    assert saved["finished"] and saved["result"] == live.task.success
    d = demos.load(saved["demo"])
    assert d.num_episodes == 1 and d.terminated[-1]
    # live and offline are one pipeline: the saved hand log converts to the same steps
    again = cv.convert_log(saved["handlog"], task, tmp_path / "again")
    assert again.installed and again.steps == len(d.actions) == saved["steps"]
    np.testing.assert_array_equal(again.actions, d.actions)
    np.testing.assert_array_equal(np.array(again.rewards, dtype=np.float32), d.rewards)
    d2 = demos.load(again.out)
    np.testing.assert_array_equal(d2.obs, d.obs)


def test_follows_the_hand_and_reports_why_not(tmp_path):
    log, live = _suction(tmp_path)

    async def go(client):
        ws, _ = await _driver(client)
        first = await _stream(ws, log)
        # the hand lost: the robot holds and the HUD says why
        await ws.send_bytes(pack_frame(99999, float(log.t[-1]) + 0.1, 0.0, None))
        lost = await ws.receive_json(timeout=10)
        return first, lost

    first, lost = _serve(TeleopServer(live), go)
    assert first[0]["why"] == "no hand yet" or first[0]["following"]
    assert not first[-1]["recording"] and first[-1]["why"] in ("not recording", None)
    assert lost["why"] == "hand not tracked"
    assert {"shoulder_link", "wrist_3_link", "tile", "tool0"} <= set(first[-1]["frames"])


def test_bad_input_is_dropped_and_counted_and_never_fatal(tmp_path):
    log, live = _suction(tmp_path)

    async def go(client):
        ws, _ = await _driver(client)
        await ws.send_bytes(b"\x00" * 10)  # wrong size
        await ws.send_bytes(b"XXXX" + b"\x00" * (FRAME_BYTES - 4))  # wrong magic
        nan = np.full((25, 3), np.nan)
        await ws.send_bytes(pack_frame(1, 0.0, 0.0, nan))  # NaN in a tracked hand
        await ws.send_str("not json")
        await ws.send_json({"type": "teleport"})
        states = await _stream(ws, log, seq0=10, until=lambda m: True)
        return states[-1]

    last = _serve(TeleopServer(live), go)
    assert last["dropped"] == {
        "malformed": 3,
        "nan": 1,
        "backwards": 0,
        "unknown": 1,
        "not_driver": 0,
    }


def test_second_client_watches_and_cannot_drive(tmp_path):
    log, live = _suction(tmp_path)

    async def go(client):
        a, _ = await _driver(client)
        b = await client.ws_connect("/ws")
        await b.send_json({"type": "hello", "protocol": 1, "role": "driver"})
        hello_b = await b.receive_json(timeout=10)  # its hello first, then the error
        err = await b.receive_json(timeout=10)
        await b.send_bytes(pack_frame(0, 0.0, 0.0, log.joints[0]))
        await b.send_json({"type": "control", "action": "start"})
        states = await _stream(a, log, until=lambda m: m["seq"] >= 8)
        watched = await b.receive_json(timeout=10)
        return err, hello_b, states[-1], watched

    err, hello_b, last, watched = _serve(TeleopServer(live), go)
    assert err["type"] == "error" and hello_b["role"] == "viewer"
    assert last["dropped"]["not_driver"] == 2 and not last["recording"]
    assert watched["type"] == "state"


def test_token_and_origin_are_checked(tmp_path):
    live = Live("suction", tmp_path / "out")

    async def go(client):
        r1 = await client.get("/ws")
        r2 = await client.get("/ws?token=wrong")
        r3 = await client.get("/ws?token=s3cret", headers={"Origin": "http://evil.example"})
        ws = await client.ws_connect("/ws?token=s3cret")
        hello = await _hello(ws)
        return r1.status, r2.status, r3.status, hello["role"]

    assert _serve(TeleopServer(live, token="s3cret"), go) == (403, 403, 403, "driver")


def test_disconnect_mid_episode_keeps_what_was_recorded(tmp_path):
    log, live = _suction(tmp_path)

    async def go(client):
        ws, _ = await _driver(client)
        await ws.send_json({"type": "control", "action": "start"})
        await _stream(ws, log, until=lambda m: m["step"] >= 40)
        await ws.close()
        for _ in range(100):  # the server notices the close
            if not live.recording:
                break
            await asyncio.sleep(0.02)

    _serve(TeleopServer(live), go)
    saved = live.last_saved
    assert saved is not None and not saved["finished"] and saved["result"] == "disconnected"
    assert saved["demo"].endswith(".mcap.partial")
    steps, info = demos.salvage(saved["demo"])
    assert info["messages"] > 0
    hand = cv.load_log(saved["handlog"])
    assert len(hand.t) > 40 * 2  # ~90 Hz frames for >= 40 steps at 25 Hz
    meta = json.dumps(saved)
    assert "disconnected" in meta


def _left(shape: str) -> np.ndarray:
    """A left hand (WebXR joints) making a shape of the hand model, somewhere to the left."""
    from mimicrete.hands import model as hm
    from mimicrete.hands.layouts import to_layout

    base = "opening" if shape == "pinch" else shape
    j = to_layout(
        hm.hand_joints(hm.GESTURE_SHAPES[base], np.eye(3), np.zeros(3), handedness="left"),
        "webxr",
    )
    if shape == "pinch":  # thumb tip on the index tip: move the thumb there
        j[4] = j[9] + 0.005
    return j + np.array([-0.3, -0.3, -0.4])


def test_left_hand_starts_stops_and_discards_without_controllers(tmp_path):
    """A left pinch held 1 s starts an episode, another stops (and saves) it; a left fist held
    1.5 s discards the one running. The right hand keeps driving meanwhile."""
    from mimicrete.teleop.protocol import parse_frame

    log, live = _suction(tmp_path)
    t = [float(log.t[0])]

    def hold(left: np.ndarray | None, seconds: float, k0: int) -> int:
        k = k0
        end = t[0] + seconds
        while t[0] < end and k < len(log.t) - 1:
            frame = pack_frame(k, t[0], 0.0, log.joints[k], left)
            live.push(parse_frame(frame))
            k += 1
            t[0] = float(log.t[k])
        return k

    k = hold(_left("opening"), 0.5, 0)
    assert not live.recording
    k = hold(_left("pinch"), 1.2, k)
    assert live.recording  # pinch held 1 s: started
    k = hold(_left("opening"), 0.3, k)
    k = hold(_left("pinch"), 1.2, k)
    assert not live.recording and live.last_saved["result"] == "stopped"
    k = hold(None, 0.3, k)
    k = hold(_left("pinch"), 1.2, k)
    assert live.recording
    k = hold(_left("fist"), 1.0, k)
    assert live.recording  # a fist must be held 1.5 s
    k = hold(_left("fist"), 0.7, k)
    assert not live.recording and live.last_result == "discarded"
    assert len(list((tmp_path / "out").glob("*.mcap*"))) == 1  # the stopped one only


def test_tls_and_token_over_https(tmp_path):
    """Off loopback the server serves HTTPS with a self-signed certificate and wants the token;
    exercised here on 127.0.0.1 (nothing may leave this machine)."""
    import ssl

    from mimicrete.teleop.server import ServerThread, self_signed, ssl_context

    cert, key = self_signed(tmp_path / "tls", "127.0.0.1")
    assert self_signed(tmp_path / "tls", "127.0.0.1") == (cert, key)  # made once, reused
    live = Live("suction", tmp_path / "out")

    async def go(port: int):
        import aiohttp

        trust = ssl.create_default_context(cafile=str(cert))
        base = f"https://127.0.0.1:{port}"
        async with aiohttp.ClientSession() as http:
            r = await http.get(f"{base}/ws", ssl=trust)
            ws = await http.ws_connect(f"{base}/ws?token=tok", ssl=trust)
            hello = await _hello(ws)
            await ws.close()
            try:  # an unknown self-signed certificate is not trusted by default
                await http.get(f"{base}/ws?token=tok", ssl=ssl.create_default_context())
                verified_without_cert = True
            except aiohttp.ClientConnectorCertificateError:
                verified_without_cert = False
            return r.status, hello["role"], verified_without_cert

    with ServerThread(TeleopServer(live, token="tok"), ssl_ctx=ssl_context(cert, key)) as run:
        result = _run(go(run.port))
    assert result == (403, "driver", False)
