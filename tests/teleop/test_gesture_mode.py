"""The gesture mode over a real WebSocket (aiohttp's test server on loopback, no browser): the
``gestures`` messages of docs/formats.md §3, samples from the parametric hand streamed as protocol
frames, the training in its worker thread while frames keep being answered, the left-hand pinch
that walks through the classes, and the requests the server refuses."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from aiohttp.test_utils import TestClient, TestServer

from mimicrete import gestures as g
from mimicrete.hands import layouts
from mimicrete.teleop.gesturemode import task_classes, user_csv_path, user_model_path
from mimicrete.teleop.left_hand import INDEX_TIP, THUMB_TIP
from mimicrete.teleop.live import Live
from mimicrete.teleop.protocol import pack_frame
from mimicrete.teleop.server import TeleopServer

QUICK = {"svc__C": [1.0, 10.0], "svc__gamma": ["scale"]}


def _right_hand(label: str, rng: np.random.Generator) -> np.ndarray:
    """A right hand of class ``label`` (WebXR joints) about where a standing user holds it."""
    while True:
        j, side = g.sample_gesture_hand(label, rng)
        if side == "right":
            return layouts.to_layout(j[None], "webxr")[0] + np.array([0.0, -0.5, -0.45])


def _pinched_left(rng: np.random.Generator) -> np.ndarray:
    j = _right_hand("opening", rng) * np.array([-1.0, 1.0, 1.0])
    j[INDEX_TIP] = j[THUMB_TIP] + 0.005
    return j


class Client:
    """A driver: sends frames one at a time and collects every message until the state that
    answers each."""

    def __init__(self, ws: Any) -> None:
        self.ws, self.seq, self.t = ws, 0, 10.0
        self.messages: list[dict[str, Any]] = []

    async def hello(self, role: str = "driver") -> dict[str, Any]:
        await self.ws.send_json({"type": "hello", "protocol": 1, "role": role, "client": "t"})
        return await self.until(lambda m: m["type"] == "hello")

    async def until(self, pred) -> dict[str, Any]:
        while True:
            m = await self.ws.receive_json(timeout=30)
            self.messages.append(m)
            if pred(m):
                return m

    async def frame(self, right: np.ndarray | None, left: np.ndarray | None = None) -> dict:
        await self.ws.send_bytes(pack_frame(self.seq, self.t, 0.0, right, left))
        self.seq += 1
        self.t += 1 / 30
        return await self.until(lambda m: m["type"] == "state")

    async def send(self, **msg: Any) -> None:
        await self.ws.send_json(msg)

    def gestures(self, event: str | None = None) -> list[dict[str, Any]]:
        return [
            m
            for m in self.messages
            if m["type"] == "gestures" and (event is None or m["event"] == event)
        ]

    def errors(self) -> list[str]:
        return [m["message"] for m in self.messages if m["type"] == "error"]


async def _session(live: Live, body) -> Any:
    server = TeleopServer(live)
    client = TestClient(TestServer(server.app()))
    await client.start_server()
    try:
        async with client.ws_connect("/ws") as ws:
            return await body(Client(ws), server)
    finally:
        await client.close()


def test_screw_classes_recorded_trained_and_used(tmp_path):
    """Five classes from the page's messages; the last sample starts the training, which runs
    while frames keep being answered; the model drives from then on and a new run finds it."""
    live = Live(
        "screw",
        tmp_path,
        gesture_samples=20,
        gesture_options={"min_interval_s": 0.0, "settle_s": 0.2, "grid": QUICK},
    )
    rng = np.random.default_rng(7)
    classes = task_classes("screw")

    async def body(c: Client, server: TeleopServer) -> dict[str, Any]:
        hello = await c.hello()
        assert hello["mode"] == "teleop" and hello["gesture_model"]["source"] == "shipped"
        status = hello["gestures"]
        assert status["type"] == "gestures" and status["event"] == "hello"
        assert not status["active"] and status["classes"] == list(classes)
        await c.send(type="gestures", action="enter", per_class=25)
        entered = await c.until(lambda m: m["type"] == "gestures")
        assert entered["event"] == "entered" and entered["target"] == 25
        assert set(entered["prompts"]) == set(classes)
        for label in classes:
            await c.send(type="gestures", action="record")  # the next class
            rec = await c.until(lambda m: m["type"] == "gestures")
            assert rec["current"] == label
            while c.gestures()[-1]["current"] == label:
                state = await c.frame(_right_hand(label, rng))
                assert state["mode"] == "gestures"
        training = c.gestures("training")
        assert len(training) == 1 and training[0]["counts"] == {k: 25 for k in classes}
        n = 0
        while not c.gestures("trained"):  # frames are answered while the training runs
            await c.frame(_right_hand("closing_fixed", rng))
            n += 1
            assert not c.gestures("train_failed"), c.gestures()[-1]["error"]
        return {"trained": c.gestures("trained")[0], "frames": n}

    out = asyncio.run(_session(live, body))
    trained = out["trained"]
    assert out["frames"] > 0
    assert not trained["training"] and trained["model"]["source"] == "user"
    r = trained["report"]
    assert r["classes"] == list(classes) and r["n_train"] + r["n_test"] == 125
    assert np.sum(r["confusion"]) == r["n_test"] and r["test_accuracy"] >= 0.9
    model_file = user_model_path(tmp_path, "screw")
    assert trained["model"]["file"] == str(model_file) == r["model"]
    assert live.desk.model_source == "user"
    data = g.read_gesture_csv(user_csv_path(tmp_path, "screw"))
    assert data.layout == "webxr" and len(data.labels) == 125
    assert sorted(set(data.sequence)) == ["1", "2", "3", "4", "5"]  # one take per class
    # the next run of the same folder
    again = Live("screw", tmp_path)
    assert again.desk.model_source == "user" and again.model.info["path"] == str(model_file)
    assert again.desk.model_status()["test_accuracy"] == r["test_accuracy"]


def test_left_pinch_walks_through_the_classes(tmp_path):
    """In the gesture mode a left pinch held 1 s records the next class, pauses it, and once
    every class is full leaves the gesture mode; it never starts an episode there."""
    live = Live(
        "grip",
        tmp_path,
        gestures=True,
        gesture_samples=10,
        gesture_options={"min_interval_s": 0.0, "settle_s": 0.0, "grid": QUICK},
    )
    rng = np.random.default_rng(1)

    async def pinch(c: Client) -> None:
        """The left pinch held 1.3 s (at 30 Hz), then let go; the right hand untracked."""
        for _ in range(40):
            await c.frame(None, _pinched_left(rng))
        await c.frame(None)

    async def body(c: Client, server: TeleopServer) -> list[str]:
        await c.hello()
        await pinch(c)  # → record "closing"
        assert c.gestures()[-1]["current"] == "closing"
        for _ in range(5):
            await c.frame(_right_hand("closing", rng))
        await pinch(c)  # → pause
        assert c.gestures()[-1]["current"] is None
        assert c.gestures()[-1]["counts"]["closing"] == 5
        for label in ("closing", "opening", "fixed"):  # closing is not full: it is redone
            await pinch(c)  # → record the next class
            assert c.gestures()[-1]["current"] == label
            while c.gestures()[-1]["current"] == label:
                await c.frame(_right_hand(label, rng))
        while not c.gestures("trained"):
            await c.frame(_right_hand("fixed", rng))
        await pinch(c)  # every class full → leave
        assert not c.gestures()[-1]["active"] and not live.recording
        await pinch(c)  # and now the pinch starts an episode
        assert live.recording
        return [m["event"] for m in c.gestures()]

    events = asyncio.run(_session(live, body))
    assert events[0] == "entered"  # Live(gestures=True), sent with the first frame
    assert events.count("recording") == 4 and events.count("paused") == 1
    assert events[-1] == "exited" and "trained" in events


def test_requests_the_server_refuses(tmp_path):
    live = Live("suction", tmp_path)

    async def body(c: Client, server: TeleopServer) -> None:
        await c.hello()
        await c.send(type="gestures", action="record")  # not in the gesture mode
        await c.until(lambda m: m["type"] == "error")
        await c.send(type="gestures", action="enter", per_class=3)  # too few
        await c.until(lambda m: m["type"] == "error")
        await c.send(type="gestures", action="enter")
        await c.until(lambda m: m["type"] == "gestures" and m["event"] == "entered")
        await c.send(type="gestures", action="record", **{"class": "grab"})
        await c.until(lambda m: m["type"] == "error")
        await c.send(type="gestures", action="train")  # no samples yet
        await c.until(lambda m: m["type"] == "error")
        await c.send(type="control", action="start")  # no episode in the gesture mode
        await c.until(lambda m: m["type"] == "error")
        await c.send(type="gestures", action="dance")
        await c.frame(None)
        # a watcher cannot drive the gesture mode
        async with server_client_ws(server) as ws2:
            v = Client(ws2)
            hello = await v.hello("driver")
            assert hello["role"] == "viewer" and hello["mode"] == "gestures"
            await v.send(type="gestures", action="exit")
            await c.frame(None)
        assert server.stats.dropped["not_driver"] == 1 and server.stats.dropped["unknown"] == 1
        assert live.desk.active and not live.recording

    server_ref: dict[str, Any] = {}

    def server_client_ws(server: TeleopServer):
        return server_ref["client"].ws_connect("/ws")

    async def run() -> list[str]:
        server = TeleopServer(live)
        client = TestClient(TestServer(server.app()))
        server_ref["client"] = client
        await client.start_server()
        try:
            async with client.ws_connect("/ws") as ws:
                c = Client(ws)
                await body(c, server)
                return c.errors()
        finally:
            await client.close()

    errors = asyncio.run(run())
    assert errors == [
        "gestures: not in the gesture mode",
        "gestures: per_class must be in 10..5000, got 3",
        "gestures: unknown class 'grab'; suction has ('closing', 'opening', 'fixed')",
        "gestures: every class needs at least 10 samples to train: closing (0), opening (0), "
        "fixed (0)",
        "start: leave the gesture mode to record an episode",
    ]


def test_a_stale_user_model_is_not_used(tmp_path):
    """A user model whose classes do not fit the task is skipped with a warning."""
    model, _ = g.train_builtin("screw", 0, QUICK)
    model.save(user_model_path(tmp_path, "suction"))
    with pytest.warns(RuntimeWarning, match="not used"):
        live = Live("suction", tmp_path)
    assert live.desk.model_source == "shipped"
    assert Path(live.desk.model_status()["file"]).name == "gesture_grip.joblib"
