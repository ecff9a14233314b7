"""`mimicrete synth-hands`: hand logs of the scripted demonstrator (`mimicrete.demonstrator`)."""

from __future__ import annotations

import argparse

from mimicrete.cli import UsageError
from mimicrete.hands.layouts import LAYOUT_JOINTS
from mimicrete.tasks import TASKS


def configure(parser: argparse.ArgumentParser) -> None:
    """Flags of ``mimicrete synth-hands``."""
    parser.add_argument("--task", choices=TASKS, default="suction", help="task to demonstrate")
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


def main(args: argparse.Namespace) -> int:
    """Run ``mimicrete synth-hands``."""
    from mimicrete.demonstrator import synth_hands

    if args.episodes < 1:
        raise UsageError(f"--episodes must be >= 1, got {args.episodes}")
    paths = synth_hands(
        args.task,
        args.episodes,
        args.seed,
        args.out,
        layout=args.layout,
        handedness=args.handedness,
        progress=True,
    )
    print(f"wrote {len(paths)} hand logs to {args.out}")
    return 0
