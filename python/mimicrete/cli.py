"""The ``mimicrete`` command line. Each subcommand lives in the module that owns its work; that
module defines ``configure(parser)`` (its flags) and ``main(args) -> int`` (its body)."""

from __future__ import annotations

import argparse
import importlib
import sys

# subcommand -> (module, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "synth-hands": ("mimicrete.synth", "write hand logs of a scripted person doing a task"),
    "convert": ("mimicrete.convert", "hand logs -> MCAP demonstrations (one file per episode)"),
    "gesture": ("mimicrete.gestures", "train / evaluate the SVM gesture models"),
    "train": ("mimicrete.learn.train", "train a policy with BC + GAIL + PPO from a YAML config"),
    "eval": ("mimicrete.learn.evaluate", "evaluate a run: picked/installed rate, episode length"),
    "inspect": ("mimicrete.demos", "show what is in an MCAP demo"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mimicrete",
        description="Hand demonstrations to robot skills: gestures, IK teleoperation, MCAP demos, "
        "BC + GAIL + PPO training and evaluation on the tile-installation task.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        mod = importlib.import_module(module)
        mod.configure(p)
        p.set_defaults(_module=module)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    mod = importlib.import_module(args._module)
    return int(mod.main(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
