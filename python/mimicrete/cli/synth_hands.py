"""`mimicrete synth-hands`: hand logs of the scripted demonstrator (`mimicrete.demonstrator`), or
with ``--through-teleop`` its demos recorded through a live ``mimicrete teleop`` server with hand
shapes captured on a Quest (`mimicrete.demonstrator.live_client`). ``--task-file SPEC.toml``: the
person demonstrates the task a spec file describes (its starts, object and target; the task's
logic, and so its gestures, follow from the spec's effector); a bad spec is one line naming the
file, the field, the value and why, exit 2. The row (``--task row``, ``tile_row.toml``): the person
installs its tiles one after another, tile ``i`` onto pad ``i``."""

from __future__ import annotations

import argparse

from mimicrete import tasks
from mimicrete.cli import UsageError, task_file_arg
from mimicrete.hands.layouts import LAYOUT_JOINTS
from mimicrete.tasks import TASKS


def configure(parser: argparse.ArgumentParser) -> None:
    """Flags of ``mimicrete synth-hands``."""
    parser.add_argument("--task", choices=TASKS, default=None, help="task to demonstrate (suction)")
    parser.add_argument(
        "--task-file",
        metavar="SPEC.toml",
        help="demonstrate the task this spec file describes (tile-sim task spec, version 1; "
        "crates/tile-sim/tasks/*.toml are the built-in ones); --task, if given, must match it. "
        "The hands map to the robot at the spec's hand scale (robot.hand_scale, else the arm's "
        "workspace over the UR3's: 1 on a UR3), so they move the UR3-size distances",
    )
    parser.add_argument("--episodes", type=int, default=60, help="hand logs to write (60)")
    parser.add_argument("--seed", type=int, default=0, help="seed: same seed, same files (0)")
    parser.add_argument("--out", required=True, metavar="DIR", help="output directory")
    parser.add_argument(
        "--layout",
        choices=sorted(LAYOUT_JOINTS),
        default="openxr",
        help="joint layout written (openxr)",
    )
    parser.add_argument(
        "--handedness",
        choices=["right", "left"],
        default="right",
        help="the demonstrating hand (right)",
    )
    parser.add_argument(
        "--through-teleop",
        action="store_true",
        help="record demos (MCAP + hand logs, as a live session writes them) through a mimicrete "
        "teleop server run here: IWER's Quest-captured hand shapes, 72 Hz with jitter, pauses, "
        "the page's protocol, the server's gesture model and clutch; real time (~13 s an "
        "episode). Right hand, WebXR layout",
    )
    parser.add_argument(
        "--mapping",
        choices=["clutch", "absolute"],
        default="clutch",
        help="with --through-teleop: how the hand drives the robot (clutch)",
    )


def main(args: argparse.Namespace) -> int:
    """Run ``mimicrete synth-hands``."""
    from mimicrete.demonstrator import check_task, synth_hands
    from mimicrete.teleop.look import offset_seen

    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    if args.task_file is not None:
        args.task = task_file_arg(args.task_file, args.task)
    args.task = args.task or "suction"
    check_task(args.task)
    if args.through_teleop:
        if args.handedness != "right" or args.layout != "openxr":
            raise UsageError(
                "--through-teleop records the page's right hand (WebXR): drop --layout/--handedness"
            )
        from mimicrete.demonstrator.live_client import record_live

        saved = record_live(
            args.task,
            args.episodes,
            args.seed,
            args.out,
            mapping=args.mapping,
            progress=True,
            task_file=args.task_file,
        )
        success = tasks.get(args.task).success
        if args.task_file is not None:  # what the spec calls it
            success = tasks.load_task_file(args.task_file)[1]["about"]["success"]
        ok = sum(s["result"] == success for s in saved)
        print(f"recorded {len(saved)} demos through mimicrete teleop to {args.out}: {ok} succeeded")
        return 0
    paths = synth_hands(
        args.task,
        args.episodes,
        args.seed,
        args.out,
        layout=args.layout,
        handedness=args.handedness,
        progress=True,
        task_file=args.task_file,
        see=offset_seen,
    )
    print(f"wrote {len(paths)} hand logs to {args.out}")
    return 0
