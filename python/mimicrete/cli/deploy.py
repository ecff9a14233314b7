"""`mimicrete deploy RUN_DIR --robot MODEL [--sim | --shadow --host IP | --live --host IP]
[--tile-pose fixed:X,Y,YAW | file:PATH] [--out DIR] [--ticks N] [--speed-cap RAD_S]` (or
`mimicrete deploy --replay LOG`: a log's commands replayed in the simulator): a trained
run's policy at 25 Hz on a robot, every command through the gates (mimicrete.robot.gates),
every tick logged as an MCAP demo in ``--out`` (``mimicrete inspect`` prints its gate counts and
latency percentiles). ``--shadow`` (the default) reads a real UR controller and sends nothing;
``--live`` moves it (docs/deploy.md: not yet met a real arm); ``--sim`` rehearses on the
simulated arm. Exit 0 when the run ended as asked (``--ticks``, the simulated episode's end), 1
when a fault stopped it (the reason printed; the log is valid), 2 for bad input or a refused
start, 130 on Ctrl-C / SIGTERM."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

from mimicrete.cli import UsageError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", nargs="?", help="a run directory written by `mimicrete train`")
    parser.add_argument(
        "--replay",
        metavar="LOG",
        help="instead of a run: replay a deploy log's commands in the simulator and compare "
        "(writes LOG's stem + _replay.mcap, or --out FILE.mcap)",
    )
    parser.add_argument(
        "--robot",
        help="the arm's model (ur3, ur3e, ur5, ur5e, ur10, ur10e); must be the one the run's task "
        "was trained on",
    )
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument(
        "--shadow",
        dest="mode",
        action="store_const",
        const="shadow",
        help="read the controller at --host, compute and log every command, send nothing (default)",
    )
    mode.add_argument(
        "--live",
        dest="mode",
        action="store_const",
        const="live",
        help="stream the gated commands to the controller with servoJ (docs/deploy.md first)",
    )
    mode.add_argument(
        "--sim", dest="mode", action="store_const", const="sim", help="the simulated arm"
    )
    parser.set_defaults(mode="shadow")
    parser.add_argument("--host", help="the controller's IP address (--shadow, --live)")
    parser.add_argument(
        "--tile-pose",
        metavar="SOURCE",
        help="where the tile is: fixed:X,Y,YAW (m, m, rad, Base frame), file:PATH (JSON lines "
        '{"x": .., "y": .., "yaw": ..}, the newest line counts) or aruco:CAMERA (a marker on the '
        "tile, --camera-calibration); --sim: where the simulated tile is put (default: the "
        "simulator's own tile, fixed:0.075,0.32,0)",
    )
    parser.add_argument(
        "--camera-calibration",
        metavar="FILE.json",
        help="--tile-pose aruco:CAMERA: the camera's intrinsics, its pose in the robot's Base "
        "frame and the marker (docs/deploy.md)",
    )
    parser.add_argument("--out", help="directory of the deploy logs (default: RUN_DIR/deploy)")
    parser.add_argument(
        "--ticks", type=int, help="stop after this many control ticks (default: until stopped)"
    )
    parser.add_argument(
        "--speed-cap",
        type=float,
        help="joint speed cap, rad/s (default: 1.0, or half the arm's slowest rated joint speed "
        "if lower)",
    )
    parser.add_argument(
        "--suction-output",
        type=int,
        default=0,
        metavar="N",
        help="the standard digital output driving the suction (--live; 0)",
    )
    parser.add_argument(
        "--release-on-stop",
        action="store_true",
        help="switch the suction off when the run stops (default: keep holding)",
    )


def main(args: argparse.Namespace) -> int:
    from mimicrete import _native
    from mimicrete.robot import RobotError
    from mimicrete.robot import deploy as dep
    from mimicrete.robot.gates import Limits, StartRefused
    from mimicrete.robot.observe import ObservationError
    from mimicrete.robot.tile_pose import TilePoseError

    if args.replay is not None:
        return _replay(args)
    if args.run_dir is None:
        raise UsageError("RUN_DIR: a run directory (or --replay LOG)")
    if args.robot is None:
        raise UsageError("--robot: the arm's model (ur3, ur3e, ur5, ur5e, ur10, ur10e)")
    run_dir = Path(args.run_dir)
    if not run_dir.is_dir():
        raise UsageError(f"{run_dir}: no such run directory")
    if args.robot not in _native.kin_models():
        raise UsageError(f"--robot {args.robot}: one of {', '.join(_native.kin_models())}")
    if args.mode in ("shadow", "live") and not args.host:
        raise UsageError(f"--{args.mode} needs --host IP (the controller's address)")
    if args.mode == "sim" and args.host:
        raise UsageError("--sim runs the simulated arm: no --host")
    if args.ticks is not None and args.ticks < 1:
        raise UsageError(f"--ticks: at least 1, got {args.ticks}")
    if not 0 <= args.suction_output <= 7:
        raise UsageError(
            f"--suction-output: a standard digital output 0..7, got {args.suction_output}"
        )
    if args.tile_pose is None and args.mode != "sim":
        raise UsageError(f"--{args.mode} needs --tile-pose (fixed:X,Y,YAW or file:PATH)")

    import torch

    from mimicrete.learn.run_files import PolicyFileError, load_policy

    torch.set_num_threads(1)
    try:
        actor, cfg = load_policy(run_dir)
    except PolicyFileError as e:
        raise UsageError(str(e)) from None
    es = cfg.env_settings
    try:
        source = parse_source(args.tile_pose or "fixed:0.075,0.32,0", args.camera_calibration)
    except TilePoseError as e:
        raise UsageError(str(e)) from None
    tile0 = source.pose()
    try:
        task = dep.Task.of_run(es.env_id, es.task_file, tile0)
    except (ValueError, _native.SimError) as e:
        source.close()
        raise UsageError(f"--tile-pose {args.tile_pose or ''}: {e}") from None
    except KeyError:
        source.close()
        raise UsageError(
            f"{run_dir}: trained on {es.env_id}, which has no robot to deploy"
        ) from None
    model = task.spec["robot"]["model"]
    if args.robot != model:
        source.close()
        raise UsageError(
            f"--robot {args.robot}: {run_dir} was trained on a {model} ({task.name}); deploy it "
            f"on a {model}"
        )
    try:
        limits = Limits.from_spec(task.spec, task.joint_step, speed_cap=args.speed_cap)
        dep.Observer(task.spec, [0.0, 0.0, 0.0])  # a task whose observation deploy cannot build
    except (ValueError, ObservationError) as e:
        source.close()
        raise UsageError(str(e)) from None

    robot: Any = None
    try:
        if args.mode == "sim":
            from mimicrete.robot.sim import SimRobot

            robot = SimRobot(task=task.env.task, task_file=task.task_file, tile_pose=tile0)
            if args.tile_pose is None:
                source = _SimTile(robot)
        elif args.mode == "shadow":
            from mimicrete.robot.rtde import ShadowRobot

            robot = ShadowRobot(args.host)
        else:
            from mimicrete.robot.rtde import LiveRobot

            robot = LiveRobot.connect(
                args.host,
                suction_output=args.suction_output,
                period=limits.period,
                speed_cap=limits.speed_cap,
                deadline=limits.deadline,
                release_on_stop=args.release_on_stop,
            )
    except RobotError as e:
        source.close()
        raise UsageError(str(e)) from None

    try:  # the robot is connected: whatever stops us now disconnects it (ur-rtde's thread)
        if args.mode == "live":
            print(
                f"LIVE on {args.host}: the arm will move (speed cap {limits.speed_cap:g} rad/s, "
                f"suction on digital output {args.suction_output}); keep a hand on the emergency "
                "stop; Ctrl-C stops it",
                file=sys.stderr,
            )
        policy = dep.torch_policy(actor)
        policy(dep.Observer(task.spec, [0.0, 0.0, 0.0]).frames.reshape(-1))  # warm up before timing
        out_dir = Path(args.out) if args.out else run_dir / "deploy"
        stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
        out = out_dir / f"deploy_{args.mode}_{stamp}.mcap"
        n = 1
        while out.exists():
            out = out_dir / f"deploy_{args.mode}_{stamp}_{n}.mcap"
            n += 1
        outcome = dep.run(
            robot,
            policy,
            task,
            source,
            out,
            limits=limits,
            ticks=args.ticks,
            meta_extra={"run_dir": str(run_dir), "host": args.host or ""},
        )
    except StartRefused as e:
        robot.stop("start refused")
        robot.close()
        source.close()
        raise UsageError(f"start refused: {e}") from None
    except KeyboardInterrupt:  # Ctrl-C before the control loop took the signals over
        robot.close()
        source.close()
        raise
    lat = outcome.latency_ms
    lat_text = f", read -> command p50 {lat['p50']:.2f} ms, p99 {lat['p99']:.2f} ms" if lat else ""
    gates = ", ".join(f"{g} {k}" for g, k in sorted(outcome.gate_counts.items())) or "none"
    print(f"{args.mode}: {outcome.ticks} ticks, gates fired: {gates}{lat_text}")
    print(f"stopped: {outcome.reason}")
    print(f"wrote {outcome.path}")
    if outcome.kind == "signal":
        return 130
    if outcome.fault:
        print(f"mimicrete deploy: stopped by a fault: {outcome.reason}", file=sys.stderr)
        return 1
    return 0


def _replay(args: argparse.Namespace) -> int:
    from mimicrete.robot.replay import ReplayError, format_summary, replay

    if args.run_dir is not None or args.host or args.mode != "shadow" or args.tile_pose:
        raise UsageError("--replay LOG takes no RUN_DIR, --host, mode or --tile-pose")
    log = Path(args.replay)
    if not log.is_file():
        raise UsageError(f"--replay {log}: no such file")
    if args.out is not None and not args.out.endswith(".mcap"):
        raise UsageError(f"--out {args.out}: with --replay, the replay's file (FILE.mcap)")
    try:
        res = replay(log, args.out)
    except ReplayError as e:
        raise UsageError(f"--replay {e}") from None
    print(format_summary(res))
    return 0


class _SimTile:
    """--sim without --tile-pose: the simulator's own tile."""

    label = "sim"

    def __init__(self, robot) -> None:
        self.robot = robot
        self.version = 0

    def pose(self):
        self.version += 1
        return self.robot.tile_pose()

    def close(self) -> None:
        pass


def parse_source(text: str, calibration: str | None = None) -> Any:
    """``fixed:X,Y,YAW``, ``file:PATH`` or ``aruco:CAMERA`` (with ``calibration``, the camera's
    calibration file) -> a tile pose source of :mod:`mimicrete.robot.tile_pose` or
    :mod:`mimicrete.robot.aruco` (``TilePoseError`` naming the flag)."""
    from mimicrete.robot.tile_pose import FileTilePose, FixedTilePose, TilePoseError

    kind, _, rest = text.partition(":")
    if kind == "fixed":
        parts = rest.split(",")
        try:
            x, y, yaw = (float(p) for p in parts)
        except ValueError:
            raise TilePoseError(
                f"--tile-pose {text}: fixed:X,Y,YAW takes three numbers (m, m, rad)"
            ) from None
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise TilePoseError(f"--tile-pose {text}: the numbers must be finite")
        return FixedTilePose(x, y, yaw)
    if kind == "file" and rest:
        return FileTilePose(rest)
    if kind == "aruco" and rest:
        from mimicrete.robot.aruco import ArucoTilePose

        return ArucoTilePose(rest, calibration)
    raise TilePoseError(f"--tile-pose {text}: expected fixed:X,Y,YAW, file:PATH or aruco:CAMERA")
