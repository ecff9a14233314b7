"""`mimicrete teleop`: record demonstrations with your own hands (the live WebXR page)."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
from typing import TYPE_CHECKING

from mimicrete.cli import UsageError, calibration_arg, gesture_model_arg, task_file_arg
from mimicrete.tasks import TASKS
from mimicrete.teleop.gesturemode import DEFAULT_PER_CLASS, MIN_PER_CLASS

if TYPE_CHECKING:
    from mimicrete.teleop.live import Live

HELP_OPEN = """\
open the page:
  Quest over USB:   adb reverse tcp:{port} tcp:{port}, then http://localhost:{port}/ in the Quest
                    Browser; Enter VR, put the controllers down, demonstrate with the right hand
  Quest over LAN:   mimicrete teleop --host 0.0.0.0 (HTTPS with a self-signed certificate and a
                    token; accept the certificate warning once)
  desktop, no headset: add ?emulate=quest3 to the URL (or pass --emulate): Meta's IWER emulates a
                    Quest with hand tracking, driven with mouse and keyboard
  left-hand pinch held 1 s starts / stops an episode; the page has Start/Stop/Discard/Recentre
  Gestures (or --gestures): teach the gesture SVM your own hand, class by class; the model is
                    saved as DIR/gesture_<task>_user.joblib and drives from then on (also in the
                    next runs with the same --out)
"""


def configure(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = HELP_OPEN.format(port=8012)
    parser.add_argument(
        "--task",
        choices=TASKS,
        help="the task to record (suction; with --task-file, the task the spec runs)",
    )
    parser.add_argument(
        "--task-file",
        metavar="SPEC.toml",
        help="record in the task this spec file describes (tile-sim task spec, version 1: its "
        "object, target, starts; docs/tasks.md); the page draws its scene, the demos and hand "
        "logs name it, and the hand moves the tool by the spec's hand scale (robot.hand_scale, "
        "else the arm's workspace over the UR3's: 1 on a UR3, ~2.6 on a UR10e)",
    )
    parser.add_argument(
        "--out", required=True, metavar="DIR", help="where demos and hand logs are saved"
    )
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="bind address (127.0.0.1; any other address serves HTTPS and needs the token)",
    )
    parser.add_argument("--port", type=int, default=8012, help="port (8012)")
    parser.add_argument("--seed", type=int, default=0, help="simulator seed of episode 0 (0)")
    parser.add_argument(
        "--calibration",
        metavar="FILE.json",
        help="tracking space -> Base calibration (default: DIR/calibration.json if a recentre "
        "saved one, else a standing user's at the task spec's hand scale)",
    )
    parser.add_argument(
        "--gesture-model",
        metavar="PATH",
        help="gesture model (default: DIR/gesture_<task>_user.joblib if the gesture mode saved "
        "one, else the shipped one)",
    )
    parser.add_argument(
        "--gestures",
        action="store_true",
        help="start in the gesture mode: record samples of each gesture class with your own "
        "hand, train (5-fold CV) and use the model",
    )
    parser.add_argument(
        "--gesture-samples",
        type=int,
        default=DEFAULT_PER_CLASS,
        metavar="N",
        help=f"samples per class in the gesture mode ({DEFAULT_PER_CLASS})",
    )
    parser.add_argument(
        "--mapping",
        choices=["clutch", "absolute"],
        default="clutch",
        help="clutch (default): Start (or Engage) captures your hand's and the tool's poses and "
        "the tool then moves by your hand's motion, in any hand orientation; Release lets you "
        "reposition. absolute: the tool goes where your hand is through the calibration (the "
        "paper's; for replaying hand logs recorded that way)",
    )
    parser.add_argument(
        "--emulate", action="store_true", help="print the URL of the desktop emulation (IWER)"
    )
    parser.add_argument(
        "--cert-dir",
        metavar="DIR",
        help="where the self-signed certificate is kept (default: DIR/.tls)",
    )


def main(args: argparse.Namespace) -> int:
    import asyncio
    from pathlib import Path

    from mimicrete.console import show_messages
    from mimicrete.teleop import server as srv
    from mimicrete.teleop.gesturemode import user_model_path
    from mimicrete.teleop.live import Live

    show_messages()  # the server's messages: episodes saved, the driver gone, trainings

    if not 0 < args.port < 65536:
        raise UsageError(f"--port must be in 1..65535, got {args.port}")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: exists and is not a directory")
    calib = calibration_arg(args.calibration)
    model = gesture_model_arg(args.gesture_model)
    if not MIN_PER_CLASS <= args.gesture_samples <= 5000:
        raise UsageError(f"--gesture-samples must be in {MIN_PER_CLASS}..5000")
    task = args.task or "suction"
    if args.task_file is not None:
        task = task_file_arg(args.task_file, args.task)
    live = Live(
        task,
        out,
        calibration=calib,
        seed=args.seed,
        model=model,
        gestures=args.gestures,
        gesture_samples=args.gesture_samples,
        mapping=args.mapping,
        task_file=args.task_file,
    )
    loopback = srv.is_loopback(args.host)
    token = None if loopback else srv.new_token()
    ssl_ctx = None
    if not loopback:
        cert, key = srv.self_signed(Path(args.cert_dir or out / ".tls"), args.host)
        ssl_ctx = srv.ssl_context(cert, key)
    server = srv.TeleopServer(live, token=token)
    if not (srv.STATIC / "index.html").exists():
        raise UsageError(
            f"the web page is not built ({srv.STATIC}); run `make web` in the repository"
        )
    scheme = "http" if loopback else "https"
    shown = "localhost" if loopback else args.host
    query = []
    if token:
        query.append(f"token={token}")
    if args.emulate:
        query.append("emulate=quest3")
    url = f"{scheme}://{shown}:{args.port}/" + ("?" + "&".join(query) if query else "")
    spec = f" ({args.task_file})" if args.task_file else ""
    print(f"mimicrete teleop: {task}{spec}, saving to {out}/ (episode {live.next_index} next)")
    if live.calibration.scale != 1.0:
        k = live.calibration.scale
        print(f"  hand scale {k:.3g}: the tool moves {k:.3g} m per metre of hand")
    print(f"  {url}")
    print(model_line(live))
    if args.gestures:
        gm = live.desk.status()
        print(
            f"gesture mode: record {' / '.join(gm['classes'])} ({gm['target']} samples each) in "
            f"the page; the model is saved as {user_model_path(out, task)}"
        )
    print(HELP_OPEN.format(port=args.port))
    sys.stdout.flush()
    # Ctrl-C, SIGTERM and SIGHUP all end `serve` the same way (its shutdown saves the episode
    # being recorded); the exit status is then 0: everything recorded is on disk
    sig = None
    try:
        sig = asyncio.run(srv.serve(server, args.host, args.port, ssl_ctx, signals=True))
    except KeyboardInterrupt:  # (before the loop took the signals over)
        pass
    except OSError as e:
        raise UsageError(f"cannot listen on {args.host}:{args.port}: {e.strerror or e}") from None
    if live.recording:
        live.stop("interrupted")
    live.close()
    with contextlib.suppress(OSError):  # the terminal may be gone (SIGHUP)
        if sig is not None:
            print(f"mimicrete teleop: stopped by {signal.Signals(sig).name}", file=sys.stderr)
        if live.last_saved:
            print(f"last episode: {live.last_saved}")
        sys.stdout.flush()
    return 0


def model_line(live: Live) -> str:
    """Which gesture model drives, for the start-up message."""
    st = live.desk.model_status()
    acc = st["test_accuracy"]
    held = f", {100 * acc:.2f} % held-out" if acc is not None else ""
    if st["source"] == "user":
        return (
            f"gesture model: yours, {st['file']} (trained in the page's gesture mode{held}); "
            "--gestures to teach it again"
        )
    if st["source"] == "given":
        return f"gesture model: {st['file']} (--gesture-model{held})"
    return (
        f"gesture model: the shipped one (synthetic hands{held}); --gestures teaches it your "
        "own hand"
    )
