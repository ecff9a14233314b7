"""The teleoperation page in a real browser (Debian's Chromium + Playwright + IWER).

No mimicrete server here: the built page is served by a throwaway static file server and its
WebSocket is answered by Playwright's ``route_web_socket`` with a minimal driver hello and one
state per frame. These are protocol round trips of the page's own code (packer, hand reader,
IWER replay); the end-to-end test against ``mimicrete teleop`` lives with the server.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mimicrete.hands.layouts import WEBXR_JOINT_NAMES
from mimicrete.hands.log import HandLogData
from mimicrete.hands.model import GESTURE_SHAPES, hand_joints, rotation_matrix
from mimicrete.teleop.protocol import JOINTS
from mimicrete.testing import page_driver as br

STATIC = Path(__file__).resolve().parents[2] / "python" / "mimicrete" / "teleop" / "static"
FRAME = struct.Struct("<4sIddII75f75f")


@pytest.fixture(scope="module")
def base_url() -> Iterator[str]:
    if not (STATIC / "main.js").exists():
        pytest.fail(f"{STATIC} has no built page: run `make web` (npm ci && npm run build in web/)")
    with br.serve_static(STATIC) as url:
        yield url


class FakeServer:
    """Answers the page's WebSocket inside Playwright: hello → driver, each frame → a state."""

    def __init__(self, page: Any, hello: dict[str, Any] | None = None) -> None:
        self.frames: list[bytes] = []
        self.texts: list[dict[str, Any]] = []
        self.hello = hello or br.driver_hello("suction")
        self.state: dict[str, Any] = {}
        self.pending: list[dict[str, Any]] = []  # sent before the next state
        page.route_web_socket("**/ws", self._connect)

    def _connect(self, ws: Any) -> None:
        ws.on_message(lambda m: self._message(ws, m))

    def _message(self, ws: Any, m: str | bytes) -> None:
        if isinstance(m, str):
            msg = json.loads(m)
            self.texts.append(msg)
            if msg.get("type") == "hello":
                ws.send(json.dumps(self.hello))
            return
        self.frames.append(m)
        while self.pending:
            ws.send(json.dumps(self.pending.pop(0)))
        seq, sent_ms = struct.unpack_from("<I", m, 4)[0], struct.unpack_from("<d", m, 16)[0]
        ws.send(
            json.dumps(
                {"type": "state", "seq": seq, "sent_ms": sent_ms, "server_ms": 0.0, **self.state}
            )
        )


def decode(frame: bytes) -> dict[str, Any]:
    assert len(frame) == 632
    magic, seq, t, sent_ms, flags, reserved, *floats = FRAME.unpack(frame)
    assert magic == b"MHF1" and reserved == 0
    right = np.array(floats[:75], dtype=np.float64).reshape(25, 3)
    left = np.array(floats[75:], dtype=np.float64).reshape(25, 3)
    return {
        "seq": seq,
        "t": t,
        "sent_ms": sent_ms,
        "flags": flags,
        "right": right if flags & 1 else None,
        "left": left if flags & 2 else None,
    }


def test_the_page_reads_the_joints_of_the_one_layout_table(chromium: Any, base_url: str) -> None:
    """The joints the page asks each XRHand for, in the wire's order, are ur3-kin's WebXR layout
    (the one table of hand layouts; the page cannot import it, so this checks the copy)."""
    page = br.open_page(chromium, f"{base_url}/", before_load=FakeServer)
    names = page.evaluate("window.__mimicrete.jointNames")
    assert tuple(names) == WEBXR_JOINT_NAMES
    assert len(names) == JOINTS
    page.close()


def test_packer_matches_the_protocol_layout(chromium: Any, base_url: str) -> None:
    """The page's packer writes PROTOCOL.md's 632-byte little-endian layout, bit for bit."""
    page = br.open_page(chromium, f"{base_url}/", before_load=FakeServer)
    rng = np.random.default_rng(3)
    cases = [
        (0, 0.0, 0.0, rng.normal(size=75), None),
        (2**32 - 1, 12345.678901, 9876.54321, None, rng.normal(size=75)),
        (7, 1.5e-3, 1e9, rng.normal(size=75) * 1e3, rng.normal(size=75) * 1e-4),
        (42, -1.0, 3.25, None, None),
    ]
    for seq, t, sent, right, left in cases:
        got = bytes(
            page.evaluate(
                "([s, t, m, r, l]) => window.__mimicrete.pack(s, t, m, r, l)",
                [
                    seq,
                    t,
                    sent,
                    None if right is None else right.tolist(),
                    None if left is None else left.tolist(),
                ],
            )
        )
        flags = (1 if right is not None else 0) | (2 if left is not None else 0)
        want = FRAME.pack(
            b"MHF1",
            seq,
            t,
            sent,
            flags,
            0,
            *(np.zeros(75) if right is None else right),
            *(np.zeros(75) if left is None else left),
        )
        assert got == want
    # and the page decodes its own frames back (float32 rounding only)
    js = (
        "(b) => { const f = window.__mimicrete.unpack(b); return [f.seq, f.t, f.flags,"
        " f.right && Array.from(f.right), f.left && Array.from(f.left)]; }"
    )
    seq, t, sent, right, left = cases[2]
    want = FRAME.pack(b"MHF1", seq, t, sent, 3, 0, *right, *left)
    back = page.evaluate(js, list(want))
    assert back[:3] == [7, 1.5e-3, 3]
    np.testing.assert_array_equal(back[3], right.astype(np.float32))
    np.testing.assert_array_equal(back[4], left.astype(np.float32))
    assert page.evaluate(js, list(FRAME.pack(b"MHF1", 1, 0.0, 0.0, 0, 0, *np.zeros(150))))[3:] == [
        None,
        None,
    ]
    assert page.mimicrete_errors == []
    page.close()


def _hand_track(times: np.ndarray, side: str, phase: float, scale: float) -> br.Track:
    """A moving, turning, gesture-changing hand in OpenXR layout, turned into WebXR by the same
    path a log takes (``track_from_log`` drops the palm)."""
    shapes = [GESTURE_SHAPES["opening"], GESTURE_SHAPES["closing"]]
    joints = []
    for t in times:
        w = 0.5 + 0.5 * np.sin(2 * np.pi * 0.7 * t + phase)
        rot = rotation_matrix(np.array([0.2, 1.0, 0.3]), 1.2 * np.sin(1.3 * t + phase))
        pos = np.array(
            [
                0.15 * np.sin(1.1 * t + phase),
                -0.3 + 0.05 * np.cos(2.1 * t),
                -0.45 + 0.08 * np.sin(0.9 * t),
            ]
        )
        if side == "left":
            pos[0] -= 0.3
        joints.append(hand_joints(shapes[0].lerp(shapes[1], w), rot, pos, scale, side))
    header = {"layout": "openxr", "space": "openxr", "handedness": side}
    log = HandLogData(header, times, np.ones(len(times), bool), np.array(joints), None, {})
    return br.track_from_log(log)


@pytest.mark.parametrize("mode", ["exact", "interpolate"])
def test_replayed_hands_reach_the_wire_unchanged(chromium: Any, base_url: str, mode: str) -> None:
    """Joints replayed through IWER come out of fillPoses, the packer and the WebSocket equal to
    the log (exact mode) or to IWER's interpolation of it (interpolate mode), within 1e-5 m."""
    # Right hand at 30 Hz for 6 s; left hand at 20 Hz, untracked for 1.2 s in the middle, so that
    # the merge, presence and hold paths are all exercised. 6 s, not less: how many frames the
    # page sends within the replay is its frame rate, which a loaded machine can cut to ~12/s.
    right = _hand_track(np.arange(180) / 30.0, "right", 0.0, 1.0)
    left = _hand_track(0.013 + np.arange(120) / 20.0, "left", 1.0, 0.9)
    left.tracked[50:74] = False
    rec = br.build_recording(right=right, left=left, mode=mode)
    json.dumps(rec)  # plain JSON: what the page receives

    fake: dict[str, FakeServer] = {}
    with br.vr_page(
        chromium,
        # IWER's dev UI loads in one mode and is left out (?devui=0, lighter) in the other
        f"{base_url}/?emulate=quest3" + ("" if mode == "exact" else "&devui=0"),
        before_load=lambda p: fake.setdefault("s", FakeServer(p)),
    ) as page:
        page.wait_for_function("() => window.__mimicrete.counts.statesReceived > 5")
        br.replay(page, rec)
        br.wait_replay_done(page, timeout_s=60)
        page.wait_for_timeout(200)
        samples = {s[0]: s for s in br.replay_samples(page)}
        frames = [decode(f) for f in list(fake["s"].frames)]
        checked = {"right": 0, "left": 0, "absent": 0}
        worst = 0.0
        between = 0  # frames whose playback clock fell strictly between two records
        record_ms = {f[0] for f in rec["frames"]}
        for f in frames:
            if f["seq"] not in samples:
                continue
            _, time_ms, index = samples[f["seq"]]
            for side in ("right", "left"):
                want = br.iwer_expected(rec, time_ms, side, index)
                got = f[side]
                assert (got is None) == (want is None), (f["seq"], side, time_ms)
                if want is None:
                    checked["absent"] += 1
                    continue
                worst = max(worst, float(np.max(np.abs(got - want))))
                checked[side] += 1
            between += time_ms not in record_ms
        print(f"{mode}: {len(frames)} frames, checked {checked}, worst |Δ| {worst:.2e} m")
        assert worst < 1e-5
        # the replay covered the log: most frames checked, both hands and the untracked gap seen
        assert checked["right"] >= 20 and checked["left"] >= 10 and checked["absent"] >= 2
        if mode == "interpolate":
            assert between >= 20  # IWER really interpolated, and we matched it
        else:
            assert between == 0
            shown = {s[2] for s in samples.values()}
            assert max(shown) == rec["mimicrete"]["records"] - 1  # reached the last record
        # the states the fake server echoed gave round-trip samples
        assert page.evaluate("window.__mimicrete.rtt.length") >= len(frames) - 5
        assert page.mimicrete_errors == []


def _scene_hello(task: str, seed: int = 0) -> dict[str, Any]:
    """A hello with the real scene of ``task`` (the demos' ``/scene``, as the server sends it)."""
    from mimicrete.teleop.session import Session
    from mimicrete.teleop.view import frame_poses, standing_calibration, view_from_base

    calib = standing_calibration()
    s = Session(task, "webxr", "right", calib, seed)
    return br.driver_hello(
        task,
        scene=s.scene_entities(),
        view_from_base=view_from_base(calib),
        frames=frame_poses(s.snapshot()),
    )


@contextmanager
def _scene_page(
    chromium: Any, base_url: str, hello: dict[str, Any], query: str = ""
) -> Iterator[tuple[Any, FakeServer]]:
    """The page (emulated Quest 3, 320 x 240) answered by a :class:`FakeServer` greeting it with
    ``hello``, once it has had a few states; ``query``: more URL parameters."""
    fake: dict[str, FakeServer] = {}
    with br.vr_page(
        chromium,
        f"{base_url}/?emulate=quest3&devui=0{query}",
        viewport=(320, 240),
        before_load=lambda p: fake.setdefault("s", FakeServer(p, hello)),
    ) as page:
        page.wait_for_function("() => window.__mimicrete.counts.statesReceived > 2")
        yield page, fake["s"]


def _drawn_after(page: Any, fake: FakeServer, state: dict[str, Any]) -> dict[str, Any]:
    """Answer the next frames with ``state`` and return what the page draws once it has it."""
    fake.state = state
    page.wait_for_function(
        "(s) => { const t = window.__mimicrete.state;"
        " return t && JSON.stringify(t.ee) === JSON.stringify(s.ee) &&"
        " JSON.stringify(t.frames) === JSON.stringify(s.frames); }",
        arg=state,
    )
    return page.evaluate("window.__mimicrete.scene()")


@pytest.mark.parametrize("task", ["suction", "grip", "screw"])
def test_end_effector_is_drawn_from_its_state(chromium: Any, base_url: str, task: str) -> None:
    """Suction cups light while suction is on; the gripper's fingers sit at ±(opening / 2 + half
    their thickness) in the tool frame; the nut turns with its frame and a ring shows the spin's
    direction. Geometry comes from the server's scene entities (``cup``, ``finger_*``, ``nut``)."""
    hello = _scene_hello(task)
    pip = "&spectator=pip&spectator_hz=10" if task == "grip" else ""  # the corner view too
    with _scene_page(chromium, base_url, hello, pip) as (page, s):
        frames = hello["frames"]
        if task == "suction":
            off = _drawn_after(page, s, {"frames": frames, "ee": {"kind": "suction", "on": False}})
            on = _drawn_after(page, s, {"frames": frames, "ee": {"kind": "suction", "on": True}})
            assert off["cups"] == on["cups"] == 4
            assert off["cupsLit"] == 0 and on["cupsLit"] == 4
        else:
            kind = "gripper" if task == "grip" else "screw"
            half = next(
                e["cubes"][0]["size"]["y"] / 2
                for e in hello["scene"]
                if e["id"].startswith("finger")
            )
            for opening in (0.085, 0.04, 0.0):
                ee: dict[str, Any] = {"kind": kind, "opening": opening}
                if kind == "screw":
                    ee.update(on=opening < 0.03, spin=0)
                drawn = _drawn_after(page, s, {"frames": frames, "ee": ee})
                y = opening / 2 + half
                assert drawn["fingers"]["finger_left"] == pytest.approx(y, abs=1e-6)
                assert drawn["fingers"]["finger_right"] == pytest.approx(-y, abs=1e-6)
        if task == "screw":
            for spin, angle in ((1, -1.0), (-1, 0.5), (0, 0.5)):
                turned = dict(frames)
                p = frames["tile"]
                turned["tile"] = [*p[:3], 0.0, 0.0, np.sin(angle / 2), np.cos(angle / 2)]
                ee = {"kind": "screw", "on": spin != 0, "spin": spin, "opening": 0.019}
                drawn = _drawn_after(page, s, {"frames": turned, "ee": ee})
                assert drawn["nutAngle"] == pytest.approx(angle, abs=1e-6)
                assert drawn["spinRing"] == (spin != 0) and drawn["spinDirection"] == spin
            # a new episode's scene (the plate and bolt move with the seed) replaces the drawn one
            other = _scene_hello(task, seed=2)
            bolt = next(e for e in other["scene"] if e["id"] == "bolt")["cylinders"][0]["pose"]
            assert (
                bolt != next(e for e in hello["scene"] if e["id"] == "bolt")["cylinders"][0]["pose"]
            )
            s.pending.append({"type": "scene", "scene": other["scene"]})
            page.wait_for_function(
                "() => window.__mimicrete.events.some((e) => e.type === 'scene')"
            )
            ee = {"kind": "screw", "on": True, "spin": 1, "opening": 0.0}
            drawn = _drawn_after(page, s, {"frames": other["frames"], "ee": ee})
            assert drawn["entities"]["bolt"] == pytest.approx([bolt["position"][k] for k in "xyz"])
            assert sorted(drawn["entities"]) == sorted(e["id"] for e in other["scene"])
            assert drawn["fingers"]["finger_left"] == pytest.approx(half, abs=1e-6)
            assert drawn["spinRing"] and drawn["nutAngle"] is not None
        if pip:
            page.wait_for_function("() => window.__mimicrete.spectator().frames > 2")
            box = page.eval_on_selector("#spectator", "(c) => c.getBoundingClientRect().toJSON()")
            assert 0 < box["width"] < 320 and box["x"] > 0  # a corner of the window
        else:
            assert page.evaluate("window.__mimicrete.spectator()") is None
        assert page.mimicrete_errors == []


def test_a_rows_tiles_are_drawn_each_in_its_own_frame(chromium: Any, base_url: str) -> None:
    """The row's scene (``tile_0`` … locked to frames ``tile_0`` …, the server's entities): each
    tile drawn where the state's frames put it, and moved when its frame moves."""
    hello = _scene_hello("row", seed=2)
    with _scene_page(chromium, base_url, hello) as (page, fake):
        frames = dict(hello["frames"])
        assert {"tile_0", "tile_1", "tile_2"} <= set(frames)
        ee = {"kind": "suction", "on": False}
        drawn = _drawn_after(page, fake, {"frames": frames, "ee": ee})
        for i in range(3):
            assert drawn["entities"][f"tile_{i}"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)
            assert drawn["frames"][f"tile_{i}"] == pytest.approx(frames[f"tile_{i}"], abs=1e-6)
        # tile 1 carried 0.22 m towards the base and 4 cm up: its frame moves, the others stay
        moved = dict(frames)
        p = frames["tile_1"]
        moved["tile_1"] = [p[0], p[1] - 0.22, p[2] + 0.04, *p[3:]]
        drawn = _drawn_after(page, fake, {"frames": moved, "ee": ee})
        assert drawn["frames"]["tile_1"][:3] == pytest.approx(moved["tile_1"][:3], abs=1e-6)
        for i in (0, 2):
            assert drawn["frames"][f"tile_{i}"] == pytest.approx(frames[f"tile_{i}"], abs=1e-6)
