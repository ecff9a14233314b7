"""End to end, as a user records a demonstration: the real ``mimicrete teleop`` server, the built
page in Debian's Chromium (Playwright, headless), IWER emulating a Quest with hand tracking, and a
scripted person's hand motion replayed through IWER's ActionPlayer. The page reads the joints
with ``XRFrame.fillPoses`` and streams them over the WebSocket; the server runs the session; the
episode installs the tile, is saved, and its hand log converts offline to the same demo."""

from __future__ import annotations

import asyncio
import shutil
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mimicrete import demos
from mimicrete.teleop import browser as br
from mimicrete.teleop import convert as cv
from mimicrete.teleop import synth as sy
from mimicrete.teleop.live import Live
from mimicrete.teleop.server import STATIC, TeleopServer, serve
from mimicrete.teleop.session import Session

SCREENSHOT = Path(__file__).resolve().parents[2] / "docs" / "figures" / "teleop_page.png"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class _Running:
    """A TeleopServer on a loopback port in a thread of its own (its own event loop)."""

    def __init__(self, server: TeleopServer) -> None:
        self.server, self.port = server, _free_port()
        self.loop = asyncio.new_event_loop()
        self.ready = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        ready = asyncio.Event()

        async def main() -> None:
            task = asyncio.ensure_future(serve(self.server, "127.0.0.1", self.port, None, ready))
            await ready.wait()
            self.ready.set()
            await task

        self.task = self.loop.create_task(main())
        try:
            self.loop.run_until_complete(self.task)
        except asyncio.CancelledError:
            pass

    def __enter__(self) -> _Running:
        self.thread.start()
        assert self.ready.wait(30), "server did not start"
        return self

    def __exit__(self, *exc: object) -> None:
        self.loop.call_soon_threadsafe(self.task.cancel)
        self.thread.join(30)


@pytest.fixture(scope="module")
def chromium() -> Iterator[Any]:
    if not (STATIC / "index.html").exists():
        pytest.fail(f"{STATIC} has no built page: run `make web`")
    with br.launch() as b:
        yield b


def _record_one(chromium, tmp_path, task: str, screenshot: Path | None = None):
    log_path = sy.synth_hands(task, 1, 5, tmp_path / "hands", layout="webxr")[0]
    log = cv.load_log(log_path)
    live = Live(
        task, tmp_path / "out", calibration=cv.calibration_of(log), seed=log.header["episode_seed"]
    )
    server = TeleopServer(live)
    with _Running(server) as run:
        # IWER's dev UI draws the headset's view into the page (only wanted for the picture)
        devui = "" if screenshot is not None else "&devui=0"
        page = br.open_page(chromium, f"http://127.0.0.1:{run.port}/?emulate=quest3{devui}")
        try:
            br.enter_vr(page)
            page.click("#btn-start")
            page.wait_for_function(
                "() => window.__mimicrete.state && window.__mimicrete.state.recording"
            )
            br.replay(page, br.build_recording(right=log))
            if screenshot is not None:  # mid-episode: the tile on the cups, on its way
                page.wait_for_function(
                    "() => window.__mimicrete.state && window.__mimicrete.state.step >= 150",
                    timeout=120_000,
                )
                screenshot.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(screenshot))
            page.wait_for_function(
                "() => window.__mimicrete.state && !window.__mimicrete.state.recording",
                timeout=120_000,
            )
            page.wait_for_timeout(300)  # a few more states reach the HUD
            hud = page.inner_text("#hud")
            errors = list(page.mimicrete_errors)
        finally:
            page.close()
    return live, server, hud, errors


def test_suction_episode_recorded_live_in_the_browser(chromium, tmp_path):
    shot = tmp_path / "teleop_page.png"
    live, server, hud, errors = _record_one(chromium, tmp_path, "suction", shot)
    assert not [e for e in errors if "pageerror" in e], errors
    # the server received 25-joint frames (binary, protocol v1) and dropped none
    assert server.stats.frames > 100
    assert sum(server.stats.dropped.values()) == 0, server.stats.dropped
    saved = live.last_saved
    assert saved is not None and saved["finished"], saved
    assert saved["result"] == "installed", saved
    assert "installed" in hud
    d = demos.load(saved["demo"])
    assert d.num_episodes == 1 and float(d.rewards.sum()) == pytest.approx(2.0)
    # live and offline are one pipeline: the saved hand log converts to the same demo
    again = cv.convert_log(saved["handlog"], "suction", tmp_path / "again")
    np.testing.assert_array_equal(again.actions, d.actions)
    np.testing.assert_array_equal(np.array(again.rewards, dtype=np.float32), d.rewards)
    # the robot followed the hand: once the hand has held still for half a second where the
    # target is reachable, tool0 is within 1 cm of it (the joint speed limit makes it lag while
    # the hand moves)
    hand = cv.load_log(saved["handlog"])
    s = Session("suction", "webxr", "right", cv.calibration_of(hand), hand.header["episode_seed"])
    checked = 0
    history: list[tuple[float, np.ndarray]] = []
    for k in range(len(hand.t)):
        for st in s.push(float(hand.t[k]), bool(hand.tracked[k]), hand.joints[k]):
            if s.target is None or st.why is not None:
                history.clear()
                continue
            history.append((st.t, s.target[:3, 3].copy()))
            window = [p for t, p in history if t >= st.t - 0.5]
            still = history[0][0] <= st.t - 0.5 and all(
                np.linalg.norm(p - window[-1]) < 1e-3 for p in window
            )
            if still:
                tool0 = np.asarray(s.env.snapshot()["tool0"]["t"])
                assert np.linalg.norm(tool0 - s.target[:3, 3]) < 0.01, (st.index, tool0)
                checked += 1
    assert checked > 10
    if SCREENSHOT.parent.exists():  # keep the README's picture current
        shutil.copy(shot, SCREENSHOT)


@pytest.mark.parametrize("task", ["grip", "screw"])
def test_grip_and_screw_pages_record_a_demo(chromium, tmp_path, task):
    live, server, hud, errors = _record_one(chromium, tmp_path, task)
    assert not [e for e in errors if "pageerror" in e], errors
    saved = live.last_saved
    assert saved is not None, hud
    d = demos.load(saved["demo"])
    assert d.num_episodes == 1 and len(d.actions) == saved["steps"] > 0
