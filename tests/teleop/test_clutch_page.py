"""The clutch in the real page, driven by IWER's hands as captured on a Quest (issue 23): the
server's default mapping, Start engages on IWER's relaxed hand in the orientation IWER holds it,
the tool moves by the hand's motion, Release lets the hand move away while the tool stays, Engage
takes up from there without a jump, and IWER's captured pinch switches the suction on with the
shipped gesture model (no gesture training first)."""

from __future__ import annotations

from typing import Any

import numpy as np

from mimicrete.teleop.live import Live
from mimicrete.teleop.server import ServerThread, TeleopServer
from mimicrete.teleop.view import HINTS, standing_calibration
from mimicrete.testing import page_driver as br


def _wait_states(page: Any, n: int = 40) -> dict[str, Any]:
    """Let ``n`` more states arrive (the hand's filter and the arm settle); the newest one."""
    k = page.evaluate("window.__mimicrete.counts.statesReceived")
    page.wait_for_function(
        "(k) => window.__mimicrete.counts.statesReceived > k", arg=k + n, timeout=60_000
    )
    return page.evaluate("window.__mimicrete.state")


def _move_hand(page: Any, dx: float, dy: float, dz: float) -> None:
    """Move IWER's right hand by (dx, dy, dz) m in the XR space (x right, y up, z back)."""
    page.evaluate(
        "([dx, dy, dz]) => { const p = window.__mimicrete.device.hands.right.position;"
        " p.set(p.x + dx, p.y + dy, p.z + dz); }",
        [dx, dy, dz],
    )


def test_iwer_hands_engage_drive_release_and_pinch(chromium, tmp_path):
    calib = standing_calibration()
    live = Live("suction", tmp_path / "out", calibration=calib, seed=11)
    assert live.mapping == "clutch"
    with (
        ServerThread(TeleopServer(live)) as run,
        br.vr_page(
            chromium, f"http://127.0.0.1:{run.port}/?emulate=quest3&devui=0", viewport=(480, 360)
        ) as page,
    ):

        def tool0() -> np.ndarray:
            return np.asarray(run.call(lambda: live.session.snapshot()["tool0"]["t"]))

        assert page.is_visible("#btn-clutch")
        before = _wait_states(page, 10)
        assert not before["recording"]
        page.click("#btn-start")
        s = _wait_states(page)
        # IWER's relaxed hand, held as IWER holds it: engaged and followed from the first frames
        assert s["recording"] and s["engaged"] and s["following"], (s["why"], s["hint"])
        assert s["hint"] is None
        steps = run.call(lambda: live.session.step_index)
        assert steps > 0
        a = tool0()
        # the tool moves by the hand's motion: 5 cm up in the room is 5 cm up in Base
        _move_hand(page, 0.0, 0.05, 0.0)
        s = _wait_states(page, 60)
        b = tool0()
        up = b - a
        assert s["following"], s["why"]
        assert abs(up[2] - 0.05 * calib.scale) < 0.005 and np.linalg.norm(up[:2]) < 0.005, up
        # released: the hand moves 10 cm away, the tool stays and the HUD says what to do
        page.click("#btn-clutch")
        s = _wait_states(page, 10)
        assert not s["engaged"] and s["why"] == "not engaged"
        assert s["hint"] == HINTS["not engaged"]
        assert page.inner_text("#btn-clutch") == "Engage"
        _move_hand(page, 0.10, -0.10, 0.0)
        _wait_states(page, 40)
        c = tool0()
        assert np.linalg.norm(c - b) < 0.002, c - b
        # engaged again: no jump (the hand's new pose is taken as where the tool is), then it
        # follows the hand's motion from there
        page.click("#btn-clutch")
        s = _wait_states(page, 20)
        assert s["engaged"] and s["following"], s["why"]
        d = tool0()
        assert np.linalg.norm(d - c) < 0.002, d - c
        _move_hand(page, 0.0, 0.05, 0.0)
        _wait_states(page, 60)
        e = tool0()
        assert abs((e - d)[2] - 0.05 * calib.scale) < 0.005, e - d
        # IWER's pinch, captured on a Quest, switches the suction on (the shipped model)
        assert not s["ee"]["on"]
        page.evaluate("() => { window.__mimicrete.device.hands.right.poseId = 'pinch'; }")
        s = _wait_states(page, 40)
        assert s["ee"]["on"], (s["gesture"], s["margin"])
        page.click("#btn-discard")
        _wait_states(page, 5)
        errors = list(page.mimicrete_errors)
    assert not errors, errors


def test_the_absolute_mapping_hides_the_engage_button(chromium, tmp_path):
    live = Live("suction", tmp_path / "out", calibration=standing_calibration(), mapping="absolute")
    with (
        ServerThread(TeleopServer(live)) as run,
        br.vr_page(
            chromium, f"http://127.0.0.1:{run.port}/?emulate=quest3&devui=0", viewport=(480, 360)
        ) as page,
    ):
        _wait_states(page, 5)
        assert not page.is_visible("#btn-clutch")
        assert page.is_visible("#btn-recentre")
