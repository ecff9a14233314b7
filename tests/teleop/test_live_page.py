"""End to end, as a user records a demonstration: the real ``mimicrete teleop`` server, the built
page in Debian's Chromium (Playwright, headless), IWER emulating a Quest with hand tracking, and a
scripted person's hand motion replayed through IWER's ActionPlayer. The page reads the joints
with ``XRFrame.fillPoses`` and streams them over the WebSocket; the server runs the session; the
episode installs the tile, is saved, and its hand log converts offline to the same demo."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from mimicrete import demonstrator as sy
from mimicrete import demos
from mimicrete.demonstrator.scene import scene_from_env
from mimicrete.kin import Calibration
from mimicrete.teleop import convert as cv
from mimicrete.teleop.live import Live
from mimicrete.teleop.server import ServerThread, TeleopServer
from mimicrete.teleop.session import Session
from mimicrete.teleop.view import standing_calibration, view_from_base
from mimicrete.testing import page_driver as br


def _standing_log(task: str, folder: Path, seed: int = 5) -> Path:
    """A scripted person's demonstration, standing at the table (``standing_calibration``: the
    table top 0.8 m below the head, the workspace 0.5 m ahead), as a WebXR hand log."""
    ep_seed = sy.episode_seeds(seed, 1)[0]
    ep = sy.synth_episode(
        scene_from_env(task, ep_seed),
        seed * 1_000_003,
        layout="webxr",
        calib=standing_calibration(),
    )
    return sy.write_handlog(folder / f"{task}_0000.handlog.jsonl", ep)


def _record_one(chromium, tmp_path, task: str, screenshot: Path | None = None):
    log = cv.load_log(_standing_log(task, tmp_path / "hands"))
    # the scripted person's log puts the hand where the tool is to go (the absolute mapping);
    # the clutch's page path: tests/teleop/test_clutch.py
    live = Live(
        task,
        tmp_path / "out",
        calibration=cv.calibration_of(log),
        seed=log.header["episode_seed"],
        mapping="absolute",
    )
    server = TeleopServer(live)
    shot: dict = {}
    with ServerThread(server) as run:
        # the picture is the page's third-person view (?spectator=1) of the emulated session
        view = "&spectator=1&spectator_hz=5" if screenshot is not None else ""
        # a small window while the episode runs (software WebGL on a loaded machine keeps the XR
        # frame rate up), the README's size for the picture
        with br.vr_page(
            chromium,
            f"http://127.0.0.1:{run.port}/?emulate=quest3&devui=0{view}",
            viewport=(480, 270),
        ) as page:
            # the recording reaches the page first (seconds on a loaded machine), so that the
            # hand starts moving as soon as the episode starts
            rec = br.build_recording(right=log)
            page.evaluate("(r) => { window.__pendingReplay = r; }", rec)
            page.click("#btn-start")
            page.wait_for_function(
                "() => window.__mimicrete.state && window.__mimicrete.state.recording"
            )
            page.evaluate(
                "(m) => window.__mimicrete.replay(window.__pendingReplay, m)",
                rec["mimicrete"]["mode"],
            )
            if screenshot is not None:  # mid-episode: the tile on the cups, on its way
                page.wait_for_function(
                    "() => { const s = window.__mimicrete.state; return s && s.ee.on; }",
                    timeout=120_000,
                )
                picked = page.evaluate("window.__mimicrete.state.step")
                page.wait_for_function(
                    "(k) => window.__mimicrete.state.step >= k",
                    arg=picked + 20,
                    timeout=120_000,
                )
                page.set_viewport_size({"width": 1280, "height": 720})
                n = page.evaluate("window.__mimicrete.spectator().frames")
                page.wait_for_function(  # a spectator frame drawn at this size, from now on
                    "(n) => window.__mimicrete.spectator().frames > n + 1", arg=n, timeout=60_000
                )
                screenshot.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(screenshot))
                shot = page.evaluate(
                    "() => ({state: window.__mimicrete.state, scene: window.__mimicrete.scene(),"
                    " hud: document.getElementById('hud').innerText,"
                    " spectator: getComputedStyle(document.getElementById('spectator')).display})"
                )
                page.set_viewport_size({"width": 480, "height": 270})
            page.wait_for_function(
                "() => window.__mimicrete.state && !window.__mimicrete.state.recording",
                timeout=120_000,
            )
            page.wait_for_timeout(300)  # a few more states reach the HUD
            hud = page.inner_text("#hud")
            errors = list(page.mimicrete_errors)
    return live, server, hud, errors, shot


def test_suction_episode_recorded_live_in_the_browser(chromium, tmp_path, figures_dir):
    shot = tmp_path / "teleop_page.png"
    live, server, hud, errors, drawn = _record_one(chromium, tmp_path, "suction", shot)
    assert not [e for e in errors if "pageerror" in e], errors
    # the picture: the third-person view over the window, mid-episode, the tile held by the
    # lit cups, the right hand tracked and the robot following it
    assert drawn["spectator"] == "block"
    assert drawn["state"]["recording"] and drawn["state"]["ee"]["on"]
    assert drawn["state"]["following"] and "right hand" in drawn["hud"], (
        drawn["state"]["why"],
        drawn["hud"],
    )
    assert drawn["scene"]["cupsLit"] == 4
    # the server received 25-joint frames (binary, protocol v1) and dropped none
    assert server.stats.frames > 100
    assert sum(server.stats.dropped.values()) == 0, server.stats.dropped
    saved = live.last_saved
    assert saved is not None and saved["finished"], saved
    assert saved["result"] == "installed", saved
    assert "installed" in hud
    d = demos.load(saved["demo"])
    assert d.num_episodes == 1 and float(d.rewards.sum()) == pytest.approx(2.0)
    # the page acknowledged the states: each control step says how stale its hand was
    stages = demos.inspect(saved["demo"])["stages"]
    steps = len(d.actions)
    assert stages["page: capture -> sent"]["n"] == steps
    assert 0.8 * steps <= stages["hand age when its state arrived"]["n"] < steps
    for name in ("page: capture -> sent", "round trip: sent -> state received"):
        assert 0.0 <= stages[name]["p50"] <= stages[name]["p99"] < 1000.0, (name, stages)
    age = stages["hand age when its state arrived"]
    assert age["p50"] >= stages["round trip: sent -> state received"]["p50"], stages
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
                tool0 = np.asarray(s.snapshot()["tool0"]["t"])
                assert np.linalg.norm(tool0 - s.target[:3, 3]) < 0.01, (st.index, tool0)
                checked += 1
    assert checked > 10
    if figures_dir is not None:  # `make figures`: the README's picture
        shutil.copy(shot, figures_dir / "teleop_page.png")


@pytest.mark.parametrize("task", ["grip", "screw"])
def test_grip_and_screw_pages_record_a_demo(chromium, tmp_path, task):
    live, server, hud, errors, _ = _record_one(chromium, tmp_path, task)
    assert not [e for e in errors if "pageerror" in e], errors
    saved = live.last_saved
    assert saved is not None, hud
    d = demos.load(saved["demo"])
    assert d.num_episodes == 1 and len(d.actions) == saved["steps"] > 0


def _still_hand(tool0_base: np.ndarray, calib, seconds: float = 60.0) -> br.Track:
    """An open right hand held still where it would put tool0 (pointing down) at
    ``tool0_base`` through ``calib``; WebXR joints in the ``local`` space, 10 Hz."""
    from mimicrete.demonstrator.scene import TOOL_DOWN, hand_pose_for_tool0
    from mimicrete.hands.log import HandLogData
    from mimicrete.hands.model import GESTURE_SHAPES, hand_joints

    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = TOOL_DOWN, tool0_base
    rot, wrist = hand_pose_for_tool0(pose, "right", calib)
    joints = hand_joints(GESTURE_SHAPES["opening"], rot, wrist, 1.0, "right")
    t = np.arange(int(seconds * 10)) / 10.0
    header = {"layout": "openxr", "space": "openxr", "handedness": "right"}
    log = HandLogData(
        header, t, np.ones(len(t), bool), np.repeat(joints[None], len(t), 0), None, {}
    )
    return br.track_from_log(log)


def test_recentre_maps_the_hand_onto_the_tool(chromium, tmp_path):
    """The user stands where the hand cannot be reached (the robot holds: target unreachable),
    presses Recentre: the server saves OUT/calibration.json, the page draws the scene with the new
    view_from_base, the hand's target is now tool0 (within 1 mm) and the robot follows; drawn
    through the new view_from_base, tool0 sits at the hand's wrist."""
    calib = standing_calibration()
    # a recentre maps the hand onto the tool: the absolute mapping's remedy (the clutch needs none)
    live = Live("suction", tmp_path / "out", calibration=calib, seed=11, mapping="absolute")
    far = np.array([0.95, 0.30, 0.25])  # Base; the UR3 reaches ~0.5 m
    hand = _still_hand(far, calib)
    wrist_local = hand.joints[0, 0]
    with ServerThread(TeleopServer(live)) as run:
        with br.vr_page(
            chromium, f"http://127.0.0.1:{run.port}/?emulate=quest3&devui=0", viewport=(480, 360)
        ) as page:
            br.replay(page, br.build_recording(right=hand))
            page.wait_for_function(
                "() => { const s = window.__mimicrete.state;"
                " return s && s.target && s.why === 'target unreachable'; }",
                timeout=60_000,
            )
            n = page.evaluate("window.__mimicrete.counts.statesReceived")
            page.wait_for_function(  # the hand frame's smoothing settles
                "(n) => window.__mimicrete.counts.statesReceived > n + 60", arg=n, timeout=60_000
            )
            before = page.evaluate("window.__mimicrete.state")
            assert before["why"] == "target unreachable"
            assert np.linalg.norm(np.array(before["target"][:3]) - far) < 0.01
            assert not (tmp_path / "out" / "calibration.json").exists()
            page.click("#btn-recentre")
            page.wait_for_function(
                "() => window.__mimicrete.events.some((e) => e.type === 'calibration')",
                timeout=30_000,
            )
            sent = next(
                e for e in page.evaluate("window.__mimicrete.events") if e["type"] == "calibration"
            )
            n = page.evaluate("window.__mimicrete.counts.statesReceived")
            page.wait_for_function(  # states computed with the new calibration
                "(n) => window.__mimicrete.counts.statesReceived > n + 3", arg=n, timeout=30_000
            )
            after = page.evaluate("window.__mimicrete.state")
            drawn = page.evaluate("window.__mimicrete.scene()")
            server_side = run.call(
                lambda: (live.session.target.copy(), live.session.snapshot()["tool0"]["t"])
            )
            errors = list(page.mimicrete_errors)
    assert not errors, errors
    # saved, and what the server sent is the saved calibration's view_from_base
    saved = Calibration.from_dict(json.loads((tmp_path / "out" / "calibration.json").read_text()))
    np.testing.assert_allclose(sent["view_from_base"], view_from_base(saved), atol=1e-12)
    np.testing.assert_allclose(view_from_base(saved), view_from_base(live.calibration), atol=1e-12)
    # the page applied it
    np.testing.assert_allclose(drawn["viewFromBase"], sent["view_from_base"], atol=1e-12)
    # the hand's target now coincides with tool0, and the robot follows again
    target, tool0 = np.array(after["target"][:3]), np.array(after["frames"]["tool0"][:3])
    assert np.linalg.norm(target - tool0) < 1e-3, (target, tool0)
    assert after["following"] and after["why"] != "target unreachable", after["why"]
    t, p = server_side
    assert np.linalg.norm(t[:3, 3] - np.asarray(p)) < 1e-3
    # drawn through the new view_from_base, the tool is at the hand (the hand frame's origin is
    # the wrist)
    m = np.asarray(sent["view_from_base"]).reshape(4, 4, order="F")
    assert np.linalg.norm((m @ [*tool0, 1.0])[:3] - wrist_local) < 1e-3
