"""Drive the teleoperation page in a real browser: Debian's Chromium through Playwright.

Used by the tests and by ``make bench``. Playwright's own browser downloads cannot work on these
machines, so the system browser ``/usr/bin/chromium`` is launched with ``executable_path``; WebGL
runs on SwiftShader (software), WebXR on Meta's IWER emulator, which the page loads for
``?emulate=quest3``.

Hands are replayed through IWER's **ActionPlayer** (iwer 2.5.0): :func:`build_recording` turns
mimicrete hand logs into an IWER recording (the format ``ActionRecorder.getRecording()`` writes),
:func:`replay` plays it from the next XR frame on, and the page's ``XRFrame.fillPoses`` then
returns the logged joint positions (to float32 rounding, < 1e-6 m). Two modes:

* ``"exact"`` (sample-and-hold): each XR frame shows exactly one log record, the latest whose time
  (from the log's first frame) is at or before the time since the replay started. Poses and
  whether a hand is present are that record's.
* ``"interpolate"``: IWER's own playback. Each XR frame advances a clock by wall-clock time and
  sets every joint to the *linear* interpolation of the positions (spherical for orientations) of
  the two records around that clock; a hand is present iff it is in the later record.
  :func:`iwer_expected` computes what the page must then see.

    >>> with launch() as browser:
    ...     page = open_page(browser, "http://127.0.0.1:8012/?emulate=quest3")
    ...     enter_vr(page)
    ...     replay(page, build_recording(right=mc.hands.log.parse("hand.jsonl")))
    ...     wait_replay_done(page)
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete.hands.layouts import WEBXR_FROM_OPENXR, WEBXR_JOINT_NAMES
from mimicrete.teleop.session import CONTROL_DT

CHROMIUM = Path("/usr/bin/chromium")
#: the built page, where the server serves it from (``make web``)
STATIC = Path(__file__).resolve().parent.parent / "teleop" / "static"
#: SwiftShader gives headless Chromium WebGL without a GPU; no sandbox because tests run as root;
#: no background traffic (the machines reach no network but package registries).
CHROMIUM_ARGS: tuple[str, ...] = (
    "--use-gl=swiftshader",
    "--enable-unsafe-swiftshader",
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
)

#: Joint radii (metres) given to IWER when a log has none (hand logs carry positions only):
#: roughly Quest's, used only to draw the spheres.
DEFAULT_RADII: tuple[float, ...] = (
    0.021,
    *(0.019, 0.012, 0.010, 0.009),
    *((0.021, 0.011, 0.009, 0.008, 0.007) * 4),
)

#: In exact mode every record is written twice, the copy this many milliseconds later (well
#: under any tracking period), so that IWER's "present iff in the next frame" sees the record
#: itself.
EXACT_COPY_DELTA_MS = 1e-3
#: In interpolate mode the last record is repeated this long after its time, so that IWER keeps
#: playing (holding the last pose) instead of stopping and handing the inputs back to its own
#: emulated hands.
HOLD_END_S = 3600.0


@dataclass
class Track:
    """One hand's samples in WebXR layout: ``t`` (T,) s, ``tracked`` (T,) bool, ``joints``
    (T, 25, 3) m, ``orientations`` (T, 25, 4) xyzw or None."""

    t: np.ndarray
    tracked: np.ndarray
    joints: np.ndarray
    orientations: np.ndarray | None = None


def track_from_log(log: Any, local_from_log: np.ndarray | None = None) -> Track:
    """A :class:`Track` from a parsed hand log (``mimicrete.hands.log.HandLogData``).

    ``webxr`` logs are taken as they are; ``openxr`` logs lose their palm joint (WebXR has no
    palm; the other 25 joints are the same joints in the same order). The positions must be in
    the XR ``local`` space: logs in ``openxr``/``webxr`` space are used as they are, any other
    space needs ``local_from_log`` (a 4×4 rigid transform; orientations are then rotated too).
    """
    layout = str(log.header.get("layout", "")).lower()
    joints = np.asarray(log.joints, dtype=np.float64)
    orient = None if log.orientations is None else np.asarray(log.orientations, np.float64)
    if layout == "openxr":
        joints = joints[:, WEBXR_FROM_OPENXR, :]
        orient = None if orient is None else orient[:, WEBXR_FROM_OPENXR, :]
    elif layout != "webxr":
        raise ValueError(f"cannot replay a {layout!r} hand log: needs webxr or openxr joints")
    space = str(log.header.get("space", ""))
    if local_from_log is None and space not in ("openxr", "webxr"):
        raise ValueError(f"hand log in space {space!r}: pass local_from_log (4x4) to replay it")
    if local_from_log is not None:
        m = np.asarray(local_from_log, dtype=np.float64)
        rot, trans = m[:3, :3], m[:3, 3]
        if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-9) or np.linalg.det(rot) < 0:
            raise ValueError("local_from_log must be a rigid transform (rotation + translation)")
        joints = joints @ rot.T + trans
        if orient is not None:
            orient = _quat_mul(_quat_from_matrix(rot), orient)
    return Track(
        t=np.asarray(log.t, dtype=np.float64),
        tracked=np.asarray(log.tracked, dtype=bool),
        joints=joints,
        orientations=orient,
    )


def _quat_from_matrix(r: np.ndarray) -> np.ndarray:
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0, 0] - r[1, 1] - r[2, 2])) / 2, r[2, 1] - r[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] + r[1, 1] - r[2, 2])) / 2, r[0, 2] - r[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0, 0] - r[1, 1] + r[2, 2])) / 2, r[1, 0] - r[0, 1])
    return np.array([x, y, z, w])


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a ⊗ b`` for xyzw quaternions; ``b`` may be (..., 4)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz,
        ],
        axis=-1,
    )


def _as_track(x: Any) -> Track | None:
    if x is None or isinstance(x, Track):
        return x
    return track_from_log(x)


def build_recording(
    right: Any = None,
    left: Any = None,
    *,
    mode: str = "exact",
    radii: Sequence[float] = DEFAULT_RADII,
) -> dict[str, Any]:
    """An IWER ActionPlayer recording that replays these hands (logs or :class:`Track`).

    The recording is ``{"schema": [[index, {...}], ...], "frames": [[ms, head xyz, head xyzw,
    [index, ray xyz, ray xyzw, [25 × (xyz, xyzw, radius)]], ...], ...]}`` (IWER's compressed
    format). The head sits at the ``local`` origin; each hand's target ray is the identity, so the
    joints' poses relative to ``local`` are exactly the logged ones. Times are milliseconds from
    the earliest sample of either hand. The two hands are merged on the union of their times:
    at each time a hand shows its latest sample at or before it (absent before its first sample
    or where it is untracked). ``recording["mimicrete"]`` says the mode, the duration and how
    many log records there are; ActionPlayer ignores it.
    """
    if mode not in ("exact", "interpolate"):
        raise ValueError(f"mode must be 'exact' or 'interpolate', not {mode!r}")
    hands = {"right": _as_track(right), "left": _as_track(left)}
    present = [(side, tr) for side, tr in hands.items() if tr is not None]
    if not present:
        raise ValueError("nothing to replay: give a right and/or a left hand")
    if len(radii) != 25:
        raise ValueError("radii: 25 values")
    times = np.unique(np.concatenate([tr.t for _, tr in present]))
    if len(times) > 1 and np.min(np.diff(times)) * 1000.0 <= 4 * EXACT_COPY_DELTA_MS:
        raise ValueError("samples closer than 4 µs cannot be replayed")
    t0 = float(times[0])
    schema = []
    for index, (side, _) in enumerate(present):
        schema.append(
            [
                index,
                {
                    "handedness": side,
                    "targetRayMode": "tracked-pointer",
                    "profiles": ["generic-hand", "generic-hand-select", "generic-trigger"],
                    "hasGrip": False,
                    "hasHand": True,
                    "hasGamepad": False,
                    "jointSequence": list(WEBXR_JOINT_NAMES),
                },
            ]
        )
    # For each union time, each hand's latest sample at or before it.
    latest = {side: np.searchsorted(tr.t, times, side="right") - 1 for side, tr in present}
    head = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    identity_ray = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    records = []
    for k, t in enumerate(times):
        ms = (float(t) - t0) * 1000.0
        frame: list[Any] = [ms, *head]
        for index, (side, tr) in enumerate(present):
            i = int(latest[side][k])
            if i < 0 or not bool(tr.tracked[i]):
                continue
            joints = tr.joints[i]
            quats = (
                tr.orientations[i]
                if tr.orientations is not None
                else np.tile([0, 0, 0, 1.0], (25, 1))
            )
            hand: list[float] = []
            for j in range(25):
                hand.extend(float(v) for v in joints[j])
                hand.extend(float(v) for v in quats[j])
                hand.append(float(radii[j]))
            frame.append([index, *identity_ray, hand])
        records.append(frame)
    duration_ms = records[-1][0]
    if mode == "exact":
        frames = []
        for rec in records:
            frames.append(rec)
            frames.append([rec[0] + EXACT_COPY_DELTA_MS, *rec[1:]])
    else:
        frames = [*records, [duration_ms + HOLD_END_S * 1000.0, *records[-1][1:]]]
    return {
        "schema": schema,
        "frames": frames,
        "mimicrete": {
            "mode": mode,
            "duration_ms": duration_ms,
            "records": len(records),
            "t0": t0,
            "hands": [side for side, _ in present],
        },
    }


def recording_hand(recording: dict[str, Any], frame: int, side: str) -> np.ndarray | None:
    """Joint positions (25, 3) of ``side`` in frame ``frame`` of an IWER recording, or None."""
    index = next((i for i, s in recording["schema"] if s["handedness"] == side), None)
    for entry in recording["frames"][frame][8:]:
        if entry[0] == index:
            data = np.asarray(entry[8], dtype=np.float64).reshape(25, 8)
            return data[:, :3]
    return None


def _f32(x: np.ndarray) -> np.ndarray:
    return np.asarray(x, dtype=np.float32).astype(np.float64)


def iwer_expected(
    recording: dict[str, Any], time_ms: float, side: str, record_index: int | None = None
) -> np.ndarray | None:
    """What ``fillPoses`` returns for ``side`` at playback time ``time_ms`` (ms from the start).

    Exact recordings: the record ``record_index`` (or the latest at or before ``time_ms``).
    Interpolating playback, as iwer 2.5.0's ``ActionPlayer.playFrame`` does it: the frame pointer
    ``p`` is the last frame whose successor is not earlier than the clock (it advances while
    ``frames[p+1].t < clock``), ``alpha = (clock − t_p) / (t_{p+1} − t_p)``, each position is
    ``a + alpha (b − a)`` of the float32-stored values; the hand is present iff it is in frame
    ``p+1``, and uses frame ``p+1``'s pose for both ends if it was absent in ``p``.
    """
    frames = recording["frames"]
    start = frames[0][0]
    clock = start + time_ms
    if recording["mimicrete"]["mode"] == "exact":
        n = recording["mimicrete"]["records"]
        if record_index is None:
            times = [frames[2 * i][0] for i in range(n)]
            record_index = max(0, int(np.searchsorted(times, clock, side="right")) - 1)
        joints = recording_hand(recording, 2 * record_index, side)
        return None if joints is None else _f32(joints)
    p = 0
    while p + 1 < len(frames) and frames[p + 1][0] < clock:
        p += 1
    q = p + 1 if p + 1 < len(frames) else p
    alpha = (clock - frames[p][0]) / (frames[q][0] - frames[p][0]) if q != p else 0.0
    b = recording_hand(recording, q, side)
    if b is None:
        return None
    a = recording_hand(recording, p, side)
    a = b if a is None else a
    a32, b32 = _f32(a), _f32(b)
    return a32 + alpha * (b32 - a32)


# ----------------------------------------------------------------------------------------------
# The browser
# ----------------------------------------------------------------------------------------------


@contextmanager
def launch(headless: bool = True, extra_args: Sequence[str] = ()) -> Iterator[Any]:
    """Launch Debian's Chromium under Playwright; yields a ``playwright.sync_api.Browser``."""
    from playwright.sync_api import sync_playwright

    if not CHROMIUM.exists():
        raise FileNotFoundError(
            f"{CHROMIUM} is missing: `apt-get install chromium` (the Makefile does this)"
        )
    with sync_playwright() as pw:
        browser = pw.chromium.launch(
            executable_path=str(CHROMIUM),
            headless=headless,
            args=[*CHROMIUM_ARGS, *extra_args],
        )
        try:
            yield browser
        finally:
            browser.close()


def open_page(
    browser: Any,
    url: str,
    *,
    viewport: tuple[int, int] = (1280, 720),
    timeout_s: float = 30.0,
    before_load: Any = None,
) -> Any:
    """Open ``url`` in a new page and wait until the page's test hook says it is ready.

    ``before_load(page)`` runs before navigation (e.g. to route the WebSocket). The page's
    console errors and uncaught exceptions are collected in ``page.mimicrete_errors``.
    """
    page = browser.new_page(viewport={"width": viewport[0], "height": viewport[1]})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(f"pageerror: {exc}"))
    page.on("console", lambda m: errors.append(f"console: {m.text}") if m.type == "error" else None)
    page.mimicrete_errors = errors
    if before_load is not None:
        before_load(page)
    page.goto(url)
    page.wait_for_function(
        "() => window.__mimicrete && window.__mimicrete.ready", timeout=timeout_s * 1000
    )
    return page


def enter_vr(page: Any, timeout_s: float = 20.0) -> None:
    """Press *Enter VR* (a real click, so the request has user activation) and wait for the
    session's first frames."""
    page.click("#btn-vr", timeout=timeout_s * 1000)
    page.wait_for_function("() => window.__mimicrete.inSession", timeout=timeout_s * 1000)


@contextmanager
def vr_page(browser: Any, url: str, **open_kw: Any) -> Iterator[Any]:
    """:func:`open_page` (``open_kw`` its keywords), then :func:`enter_vr`; the page is closed
    when the block ends."""
    page = open_page(browser, url, **open_kw)
    try:
        enter_vr(page)
        yield page
    finally:
        page.close()


def replay(page: Any, recording: dict[str, Any], mode: str | None = None) -> None:
    """Start replaying ``recording`` (from :func:`build_recording`) in an emulated session."""
    mode = mode or recording["mimicrete"]["mode"]
    page.evaluate("([r, m]) => window.__mimicrete.replay(r, m)", [recording, mode])


def wait_replay_done(page: Any, timeout_s: float = 120.0) -> None:
    """Wait until the playback clock has passed the last record."""
    page.wait_for_function("() => window.__mimicrete.replayDone()", timeout=timeout_s * 1000)


def replay_samples(page: Any) -> list[tuple[int, float, int | None]]:
    """``(seq, playback ms, record index or None)`` of each hand frame the page sent while
    replaying."""
    return [tuple(s) for s in page.evaluate("() => window.__mimicrete.replaySamples")]


# ----------------------------------------------------------------------------------------------
# The built page without a mimicrete server; IWER's own hand poses as a frame source
# ----------------------------------------------------------------------------------------------


@contextmanager
def serve_static(directory: str | Path | None = None) -> Iterator[str]:
    """Serve the built page (``teleop/static``, or ``directory``) on a loopback port, laid out
    as the real server does (``/`` → index.html, ``/static/x`` → x); yields the base URL."""
    import functools
    import http.server
    import threading

    root = Path(directory) if directory else STATIC
    if not (root / "index.html").exists():
        raise FileNotFoundError(f"{root} has no built page: run `make web`")

    class Handler(http.server.SimpleHTTPRequestHandler):
        def translate_path(self, path: str) -> str:
            path = path.split("?", 1)[0]
            rel = "index.html" if path == "/" else path.removeprefix("/static/")
            return str(root / rel)

        def log_message(self, *args: Any) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Handler))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


def driver_hello(task: str = "grip", **fields: Any) -> dict[str, Any]:
    """The hello a stand-in server gives the driver: WebXR joints, 25 Hz control, no scene and
    the identity view unless ``fields`` (scene, view_from_base, frames, ...) say otherwise."""
    return {
        "type": "hello",
        "protocol": 1,
        "role": "driver",
        "task": task,
        "layout": "webxr",
        "control_dt": CONTROL_DT,
        "scene": [],
        "view_from_base": list(np.eye(4).ravel()),
        "frames": {},
        **fields,
    }


class FrameSink:
    """Answers the page's WebSocket inside Playwright (``page.route_web_socket``): a driver hello,
    then one empty state per hand frame; keeps the hand frames (parsed,
    :func:`mimicrete.teleop.protocol.parse_frame`) in ``frames``. Install it before the page
    loads (``open_page(..., before_load=FrameSink)``)."""

    def __init__(self, page: Any, task: str = "grip") -> None:
        self.frames: list[Any] = []
        self.hello = driver_hello(task)
        page.route_web_socket("**/ws", self._connect)

    def _connect(self, ws: Any) -> None:
        ws.on_message(lambda m: self._message(ws, m))

    def _message(self, ws: Any, m: str | bytes) -> None:
        import json

        from mimicrete.teleop.protocol import parse_frame

        if isinstance(m, str):
            if json.loads(m).get("type") == "hello":
                ws.send(json.dumps(self.hello))
            return
        f = parse_frame(m)
        self.frames.append(f)
        ws.send(json.dumps({"type": "state", "seq": f.seq, "sent_ms": f.sent_ms, "server_ms": 0}))


#: IWER's hand poses (captured on a Quest 3), by ``device.hands.<side>.poseId``.
IWER_POSES: tuple[str, ...] = ("default", "pinch", "point")


class IwerPoseSource:
    """A :class:`mimicrete.gestures.recorder.FrameSource` made of IWER's emulated hand in a page
    that is in VR: ``prompt(label)`` sets the hand's pose (``poses[label]``, an IWER poseId),
    ``frames()`` moves and turns the hand about the workspace (a smooth random path, set with
    ``page.evaluate`` on ``window.__mimicrete.device``) and yields the right-hand frames the page
    sends, ``(t, tracked, joints (25, 3) webxr)``.

    Args:
        page: an open page in an emulated session, with a :class:`FrameSink` routed.
        sink: that sink.
        poses: class label → IWER poseId (``default``, ``pinch``, ``point``).
        seed: of the path.
        step_ms: how long each pose of the path is shown.
        turn_deg: largest rotation away from the start orientation, about each axis.
        reach_m: half-size of the box the hand wanders in, around its start position.
    """

    def __init__(
        self,
        page: Any,
        sink: FrameSink,
        poses: dict[str, str],
        *,
        seed: int = 0,
        side: str = "right",
        step_ms: float = 40.0,
        turn_deg: float = 45.0,
        reach_m: float = 0.15,
    ) -> None:
        for label, pose in poses.items():
            if pose not in IWER_POSES:
                raise ValueError(f"{label}: unknown IWER pose {pose!r}; known: {IWER_POSES}")
        self.page, self.sink, self.poses, self.side = page, sink, poses, side
        self.rng = np.random.default_rng(seed)
        self.step_ms, self.turn, self.reach = step_ms, np.radians(turn_deg), reach_m
        self.home = page.evaluate(
            f"() => {{ const h = window.__mimicrete.device.hands.{side};"
            " const p = h.position, q = h.quaternion; return [p.x, p.y, p.z, q.x, q.y, q.z, q.w]; }"
        )
        self._goal = self._random_pose()
        self._pose = np.array([0.0] * 6)

    def _random_pose(self) -> np.ndarray:
        return np.concatenate(
            [
                self.rng.uniform(-1, 1, size=3) * self.reach,
                self.rng.uniform(-1, 1, size=3) * self.turn,
            ]
        )

    def _apply(self, pose: np.ndarray) -> None:
        x, y, z = (np.asarray(self.home[:3]) + pose[:3]).tolist()
        half = pose[3:] / 2.0  # small rotations composed about x, y, z, then the home one
        qs = [
            np.array([np.sin(half[0]), 0, 0, np.cos(half[0])]),
            np.array([0, np.sin(half[1]), 0, np.cos(half[1])]),
            np.array([0, 0, np.sin(half[2]), np.cos(half[2])]),
        ]
        q = np.asarray(self.home[3:], dtype=np.float64)
        for r in qs:
            q = _quat_mul(q, r)
        self.page.evaluate(
            "([s, p, q]) => { const h = window.__mimicrete.device.hands[s];"
            " h.position.set(p[0], p[1], p[2]); h.quaternion.set(q[0], q[1], q[2], q[3]); }",
            [self.side, [x, y, z], q.tolist()],
        )

    def prompt(self, label: str) -> None:
        self.page.evaluate(
            "([s, id]) => { window.__mimicrete.device.hands[s].poseId = id; }",
            [self.side, self.poses[label]],
        )

    def frames(self) -> Iterator[tuple[float, bool, np.ndarray]]:
        seen = len(self.sink.frames)
        while True:
            d = self._goal - self._pose
            if np.linalg.norm(d) < 1e-3:
                self._goal = self._random_pose()
                d = self._goal - self._pose
            self._pose = self._pose + d * min(1.0, 0.15 / max(np.linalg.norm(d), 1e-9))
            self._apply(self._pose)
            self.page.wait_for_timeout(self.step_ms)  # frames arrive while Playwright waits
            new = self.sink.frames[seen:]
            seen += len(new)
            for f in new:
                tracked = f.right_tracked if self.side == "right" else f.left_tracked
                yield f.t, tracked, (f.right if self.side == "right" else f.left)


__all__ = [
    "CHROMIUM",
    "CHROMIUM_ARGS",
    "DEFAULT_RADII",
    "FrameSink",
    "IWER_POSES",
    "IwerPoseSource",
    "Track",
    "WEBXR_JOINT_NAMES",
    "build_recording",
    "driver_hello",
    "enter_vr",
    "iwer_expected",
    "launch",
    "open_page",
    "recording_hand",
    "replay",
    "replay_samples",
    "serve_static",
    "track_from_log",
    "vr_page",
    "wait_replay_done",
]
