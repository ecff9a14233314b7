"""The live teleoperation server (``mimicrete teleop``): serves the WebXR page and one WebSocket.

Per binary hand frame from the driving client: decode (:mod:`.protocol`), push into the live
episode (:class:`.live.Live`, the same :class:`.session.Session` ``mimicrete convert`` runs), and
answer with the state (robot frames, gesture, following or why not, episode, recording, result,
the frame's ``sent_ms`` echoed for the round trip, and the time the server spent on it).

Bad input (a frame of the wrong size, NaN, garbage, an unknown message type) is dropped and
counted, never fatal; so is a frame whose time goes back during a recording (``backwards``). One
driver at a time: a second client watches read-only. A disconnect mid-episode, and (through
:func:`serve`'s one handler for all three) Ctrl-C, SIGTERM (``kill``) or SIGHUP (the terminal
closed), finish the demo as ``TASK_NNNN.mcap.partial``, marked ``result`` ``disconnected`` or
``interrupted`` and ``finished`` false, and write the whole hand log; nothing recorded is lost.

The gesture mode (``{"type":"gestures",...}`` messages, :mod:`.gesturemode`): the driver's
right-hand frames become labelled samples of the task's gesture classes; the training runs in a
worker thread and wakes the event loop when it ends, so hand frames keep being answered while it
runs, and the trained model drives from then on.

Security: loopback by default. Any other bind address needs TLS (a self-signed certificate made
on first run) and a per-run token in the page's URL and on the WebSocket (compared in constant
time). Cross-origin WebSocket upgrades are refused.
"""

from __future__ import annotations

import asyncio
import hmac
import ipaddress
import json
import logging
import secrets
import signal
import socket
import ssl
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from aiohttp import WSMsgType, web

from .gesturemode import GestureModeError
from .live import Live
from .protocol import VERSION, FrameError, parse_frame
from .session import CONTROL_DT
from .stage_times import parse_ack
from .view import view_from_base

STATIC = Path(__file__).resolve().parent / "static"


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


@dataclass
class Stats:
    """Counters the HUD and the log show."""

    frames: int = 0
    dropped: dict[str, int] = field(
        default_factory=lambda: {
            "malformed": 0,
            "nan": 0,
            "backwards": 0,
            "unknown": 0,
            "not_driver": 0,
        }
    )
    frame_times: deque[float] = field(default_factory=deque)  # arrival times, last second
    # per frame, received → state sent, ms (the benchmark reads it)
    server_ms: list[float] = field(default_factory=list)
    # the same span in this thread's CPU time: without the waits for a core on a busy machine
    server_cpu_ms: list[float] = field(default_factory=list)

    def fps(self, now: float) -> float:
        while self.frame_times and now - self.frame_times[0] > 1.0:
            self.frame_times.popleft()
        return float(len(self.frame_times))


class TeleopServer:
    """The aiohttp application around one :class:`Live`."""

    def __init__(self, live: Live, *, token: str | None = None, static: Path = STATIC) -> None:
        self.live = live
        self.token = token
        self.static = static
        self.driver: web.WebSocketResponse | None = None
        self.viewers: set[web.WebSocketResponse] = set()
        self.stats = Stats()
        self.log = _log

    def app(self) -> web.Application:
        app = web.Application()
        app.router.add_get("/", self.index)
        app.router.add_get("/ws", self.websocket)
        if self.static.is_dir():
            app.router.add_static("/static/", self.static)
        app.on_startup.append(self._startup)
        app.on_shutdown.append(self._shutdown)
        return app

    async def _startup(self, app: web.Application) -> None:
        loop = asyncio.get_running_loop()
        # a training that ends in its worker thread wakes this loop, which applies it and tells
        # the clients even when no hand frame comes
        self.live.notify = lambda: loop.call_soon_threadsafe(self._wake)

    def _wake(self) -> None:
        self.live.desk.poll()
        asyncio.ensure_future(self._flush_events())

    # ------------------------------------------------------------------ http

    def _token_ok(self, request: web.Request) -> bool:
        if self.token is None:
            return True
        given = request.query.get("token", "")
        return hmac.compare_digest(given.encode(), self.token.encode())

    async def index(self, request: web.Request) -> web.StreamResponse:
        if not self._token_ok(request):
            raise web.HTTPForbidden(text="mimicrete teleop: a valid ?token= is required")
        page = self.static / "index.html"
        if not page.exists():
            raise web.HTTPNotFound(
                text="mimicrete teleop: the page is not built (run `make web` in the repository)"
            )
        return web.FileResponse(page, headers={"Cache-Control": "no-store"})

    # ------------------------------------------------------------------ websocket

    async def websocket(self, request: web.Request) -> web.StreamResponse:
        if not self._token_ok(request):
            raise web.HTTPForbidden(text="bad token")
        origin = request.headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc != request.host:
            raise web.HTTPForbidden(text="cross-origin WebSocket refused")
        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=1 << 16)
        await ws.prepare(request)
        role = "viewer"
        try:
            async for msg in ws:
                if msg.type == WSMsgType.BINARY:
                    if ws is not self.driver:
                        self.stats.dropped["not_driver"] += 1
                        continue
                    await self._frame(ws, msg.data)
                elif msg.type == WSMsgType.TEXT:
                    role = await self._text(ws, msg.data, role)
                elif msg.type == WSMsgType.ERROR:
                    break
        finally:
            if ws is self.driver:
                self.driver = None
                if self.live.recording:
                    self.live.stop("disconnected")
                    self.log(f"driver disconnected mid-episode; kept {self.live.last_saved}")
            self.viewers.discard(ws)
        return ws

    async def _text(self, ws: web.WebSocketResponse, data: str, role: str) -> str:
        try:
            msg = json.loads(data)
            kind = msg["type"]
        except (ValueError, KeyError, TypeError):
            self.stats.dropped["malformed"] += 1
            return role
        if kind == "hello":
            want = msg.get("role", "driver")
            refused = want == "driver" and self.driver is not None
            if want == "driver" and not refused:
                self.driver, role = ws, "driver"
            else:
                role = "viewer"
                self.viewers.add(ws)
            await ws.send_json(self._hello(role))  # the answer to a hello comes first
            if refused:
                await ws.send_json({"type": "error", "message": "another client drives; you watch"})
        elif kind == "gestures" and ws is self.driver:
            try:
                self._gestures(msg)
            except GestureModeError as e:
                await ws.send_json({"type": "error", "message": f"gestures: {e}"})
            await self._flush_events()
        elif kind == "gestures":
            self.stats.dropped["not_driver"] += 1
        elif kind == "control" and ws is self.driver:
            try:
                await self._control(str(msg.get("action")))
            except Exception as e:  # a failed save must not take the server down
                self.log(f"control {msg.get('action')!r} failed: {e}")
                await ws.send_json({"type": "error", "message": f"{msg.get('action')}: {e}"})
        elif kind == "control":
            self.stats.dropped["not_driver"] += 1
        elif kind == "ack" and ws is self.driver:
            try:
                self.live.acked(parse_ack(msg))
            except ValueError:
                self.stats.dropped["malformed"] += 1
        else:
            self.stats.dropped["unknown"] += 1
        return role

    def _hello(self, role: str) -> dict[str, Any]:
        live = self.live
        return {
            "type": "hello",
            "protocol": VERSION,
            "role": role,
            "task": live.task.name,
            "layout": "webxr",
            "control_dt": CONTROL_DT,
            "mapping": live.mapping,
            "scene": live.scene,
            "view_from_base": view_from_base(live.calibration),
            "mode": "gestures" if live.desk.active else "teleop",
            "gesture_model": live.desk.model_status(),
            "gestures": live.desk.status("hello"),
            **{k: v for k, v in live.state().items() if k == "frames"},
        }

    def _gestures(self, msg: dict[str, Any]) -> None:
        """A gesture-mode request of the driver (docs/formats.md §3)."""
        live, action = self.live, msg.get("action")
        if action == "enter":
            live.desk.enter(msg.get("per_class"), live.recording)
        elif action == "exit":
            live.desk.exit()
        elif action == "record":
            label = msg.get("class")
            if label is not None and not isinstance(label, str):
                raise GestureModeError(f"class must be a string, got {label!r}")
            live.desk.record(label)
        elif action == "pause":
            live.desk.pause()
        elif action == "train":
            live.desk.train()
        elif action == "status":
            live.events.append(live.desk.status())
        else:
            self.stats.dropped["unknown"] += 1

    async def _control(self, action: str) -> None:
        live = self.live
        if action == "start":
            live.start()
        elif action == "stop":
            live.stop()
        elif action == "discard":
            live.discard()
        elif action in ("engage", "release"):
            live.clutch(action == "engage")
        elif action == "recentre":
            m = live.recentre()
            if m is not None:
                await self._broadcast({"type": "calibration", "view_from_base": m})
            elif self.driver is not None:
                why = "not while recording" if live.recording else "no tracked hand yet"
                await self.driver.send_json({"type": "error", "message": f"recentre: {why}"})
        else:
            self.stats.dropped["unknown"] += 1
        await self._flush_events()

    async def _frame(self, ws: web.WebSocketResponse, data: bytes) -> None:
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            f = parse_frame(data)
        except FrameError as e:
            self.stats.dropped[e.kind] += 1
            return
        try:
            self.live.push(f, recv_ms=t0 * 1000.0)
        except FrameError as e:  # its time goes back: dropped like any bad frame
            self.stats.dropped[e.kind] += 1
            return
        self.stats.frames += 1
        self.stats.frame_times.append(time.monotonic())
        state = self.live.state()
        state.update(
            seq=f.seq,
            sent_ms=f.sent_ms,
            dropped=dict(self.stats.dropped),
            fps=self.stats.fps(time.monotonic()),
        )
        # in the message: frame received → state built; in the stats: → state sent (handed to
        # the socket's transport, after serialising)
        state["server_ms"] = (time.perf_counter() - t0) * 1000.0
        await ws.send_str(json.dumps(state))
        t1 = time.perf_counter()
        self.live.state_sent(f.seq, t1 * 1000.0)
        self.stats.server_ms.append((t1 - t0) * 1000.0)
        self.stats.server_cpu_ms.append((time.thread_time() - c0) * 1000.0)
        if self.viewers and f.seq % 4 == 0:  # ~25 Hz to watchers at a 90 Hz stream
            await self._broadcast(state, viewers_only=True)
        await self._flush_events()

    async def _flush_events(self) -> None:
        while self.live.events:
            ev = self.live.events.pop(0)
            if ev["type"] == "gestures":
                if ev["event"] != "progress":  # not each sample
                    self.log(_gesture_line(ev))
            elif ev["type"] != "scene":  # (the scene of a new episode: too long to print)
                self.log(json.dumps(ev))
            await self._broadcast(ev)

    async def _broadcast(self, msg: dict[str, Any], viewers_only: bool = False) -> None:
        targets = set(self.viewers) if viewers_only else {*self.viewers, self.driver}
        text = json.dumps(msg)
        for ws in targets:
            if ws is not None and not ws.closed:
                try:
                    await ws.send_str(text)
                except ConnectionError:
                    pass

    async def _shutdown(self, app: web.Application) -> None:
        if self.live.recording:
            self.live.stop("interrupted")
        self.live.notify = None
        self.live.close()  # every stopped episode and a training in progress on disk
        if self.live.last_saved and self.live.last_saved["result"] == "interrupted":
            self.log(f"stopped mid-episode; kept {self.live.last_saved}")
        for ws in [self.driver, *self.viewers]:
            if ws is not None:
                await ws.close()


logger = logging.getLogger(__name__)


def _log(msg: str) -> None:
    """What the server says (episodes saved, the driver gone, gesture trainings) as information
    of the package's log (``mimicrete teleop`` shows it: :func:`mimicrete.console.show_messages`;
    a terminal that is gone, SIGHUP, does not stop a save: logging reports and goes on)."""
    logger.info(msg)


def _gesture_line(ev: dict[str, Any]) -> str:
    """One log line for a gesture-mode event."""
    counts = ", ".join(f"{c} {n}/{ev['target']}" for c, n in ev["counts"].items())
    line = f"gestures {ev['event']}: {counts}"
    r = ev.get("report")
    if ev["event"] == "trained" and r:
        line += (
            f"; held-out accuracy {100 * r['test_accuracy']:.2f} % on {r['n_test']} samples, "
            f"5-fold CV {100 * r['cv_accuracy']:.2f} %; saved {r['model']} (from {r['csv']})"
        )
    if ev.get("error"):
        line += f"; {ev['error']}"
    return line


# ----------------------------------------------------------------------------------------------
# TLS
# ----------------------------------------------------------------------------------------------


def self_signed(cert_dir: Path, host: str) -> tuple[Path, Path]:
    """A self-signed certificate for ``host`` (and localhost), made once and reused."""
    cert, key = cert_dir / "teleop-cert.pem", cert_dir / "teleop-key.pem"
    if cert.exists() and key.exists():
        return cert, key
    import datetime

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    k = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "mimicrete teleop")])
    alt: list[x509.GeneralName] = [x509.DNSName("localhost")]
    try:
        alt.append(x509.IPAddress(ipaddress.ip_address(host)))
    except ValueError:
        alt.append(x509.DNSName(host))
    now = datetime.datetime.now(datetime.UTC)
    c = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(k.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=365))
        .add_extension(x509.SubjectAlternativeName(alt), critical=False)
        .sign(k, hashes.SHA256())
    )
    cert_dir.mkdir(parents=True, exist_ok=True)
    key.write_bytes(
        k.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    key.chmod(0o600)
    cert.write_bytes(c.public_bytes(serialization.Encoding.PEM))
    return cert, key


def ssl_context(cert: Path, key: Path) -> ssl.SSLContext:
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    ctx.load_cert_chain(str(cert), str(key))
    return ctx


def new_token() -> str:
    return secrets.token_urlsafe(16)


async def serve(
    server: TeleopServer,
    host: str,
    port: int,
    ssl_ctx: ssl.SSLContext | None,
    ready: asyncio.Event | None = None,
    *,
    signals: bool = False,
) -> int | None:
    """Serve the app on ``host:port`` until cancelled or, with ``signals`` (the main thread of
    ``mimicrete teleop``), until one of :data:`STOP_SIGNALS` arrives; returns its number.

    The three signals go through one handler and one way out: the app's shutdown stops the
    episode being recorded as ``interrupted``, waits until its demo and hand log are on disk,
    and closes the clients. A signal the process was started ignoring (``nohup`` ignores SIGHUP)
    stays ignored; one that comes while the save runs changes nothing."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    got: list[int] = []

    def on_signal(sig: int) -> None:
        got.append(sig)
        stop.set()

    installed = []
    if signals:
        for sig in STOP_SIGNALS:
            if signal.getsignal(sig) is not signal.SIG_IGN:
                loop.add_signal_handler(sig, on_signal, sig)
                installed.append(sig)
    try:
        runner = web.AppRunner(server.app(), handle_signals=False, access_log=None)
        await runner.setup()
        try:
            site = web.TCPSite(runner, host, port, ssl_context=ssl_ctx)
            await site.start()
            if ready is not None:
                ready.set()
            await stop.wait()
        finally:
            await runner.cleanup()
    finally:
        for sig in installed:
            loop.remove_signal_handler(sig)
    return got[0] if got else None


#: The signals that end ``mimicrete teleop`` through its shutdown: Ctrl-C, ``kill``, a closed
#: terminal.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


class ServerThread:
    """A :class:`TeleopServer` on a free loopback port, served by an event loop in a thread of its
    own (tests and benchmarks drive it from the main thread)::

        with ServerThread(TeleopServer(live)) as run:
            url = f"http://127.0.0.1:{run.port}/"
    """

    def __init__(
        self, server: TeleopServer, host: str = "127.0.0.1", ssl_ctx: ssl.SSLContext | None = None
    ) -> None:
        self.server, self.host, self.ssl_ctx = server, host, ssl_ctx
        with socket.socket() as s:
            s.bind((host, 0))
            self.port = int(s.getsockname()[1])
        self.loop = asyncio.new_event_loop()
        self.ready = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True, name="teleop-server")

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        ready = asyncio.Event()

        async def main() -> None:
            task = asyncio.ensure_future(
                serve(self.server, self.host, self.port, self.ssl_ctx, ready)
            )
            await ready.wait()
            self.ready.set()
            await task

        self.task = self.loop.create_task(main())
        try:
            self.loop.run_until_complete(self.task)
        except asyncio.CancelledError:
            pass

    def call(self, fn: Any) -> Any:
        """Run ``fn()`` on the server's loop (between messages) and return its result."""
        done = threading.Event()
        out: list[Any] = []
        self.loop.call_soon_threadsafe(lambda: (out.append(fn()), done.set()))
        if not done.wait(30):
            raise TimeoutError("the server loop did not answer")
        return out[0]

    def __enter__(self) -> ServerThread:
        self.thread.start()
        if not self.ready.wait(30):
            raise TimeoutError("the teleop server did not start")
        return self

    def __exit__(self, *exc: object) -> None:
        self.loop.call_soon_threadsafe(self.task.cancel)
        self.thread.join(30)
