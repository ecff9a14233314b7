"""The ``mimicrete`` command line, in one place.

Each subcommand is a module of this package with ``configure(parser)`` (its flags) and
``main(args) -> int`` (parse what the flags say, call library functions, print). The modules
import nothing heavy at the top (no torch, no scikit-learn), so ``mimicrete --help`` answers at
once; the library is imported inside ``main``.

Errors: a :class:`UsageError` (bad input the user can fix: a missing file, a bad config field, a
malformed hand log) prints one line ``mimicrete <cmd>: error: <what>`` and exits 2; any other
failure exits 1 with its message; Ctrl-C exits 130. ``--debug`` shows the traceback instead.
"""

from __future__ import annotations

import argparse
import importlib
import sys

# subcommand -> (module in this package, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "synth-hands": ("synth_hands", "write hand logs of a scripted person doing a task"),
    "convert": ("convert", "hand logs -> MCAP demonstrations (one file per episode)"),
    "teleop": (
        "teleop",
        "live teleoperation: the WebXR page drives the robot, episodes are recorded",
    ),
    "gesture": ("gesture", "train / evaluate the SVM gesture models"),
    "train": ("train", "train a policy with BC + GAIL + PPO from a YAML config"),
    "eval": ("eval", "evaluate a run: picked/installed rate, episode length"),
    "inspect": ("inspect", "show what is in an MCAP demo and check it"),
    "export": ("export", "MCAP demos -> a LeRobot v3.0 or Minari dataset (one task per dataset)"),
}


class UsageError(Exception):
    """Bad input the user can fix; printed as one line, exit code 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mimicrete",
        description="Hand demonstrations to robot skills: gestures, IK teleoperation, MCAP demos, "
        "BC + GAIL + PPO training and evaluation on the tile-installation task.",
    )
    parser.add_argument(
        "--debug", action="store_true", help="show the Python traceback of an error"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, (module, help_text) in COMMANDS.items():
        p = sub.add_parser(name, help=help_text, description=help_text)
        p.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help=argparse.SUPPRESS
        )
        mod = importlib.import_module(f"{__name__}.{module}")
        mod.configure(p)
        p.set_defaults(_module=f"{__name__}.{module}")
    return parser


def gesture_model_arg(path: str | None):  # -> GestureModel | None (no import of it here)
    """The gesture model a ``--gesture-model PATH`` flag names, loaded (None: no flag, the shipped
    one is used); a file that is missing or not a model is a :class:`UsageError` naming the flag."""
    if not path:
        return None
    from mimicrete.gestures import load_model

    try:
        return load_model(path)
    except (OSError, ValueError, KeyError, EOFError) as e:
        raise UsageError(f"--gesture-model {path}: {e}") from None


def user_errors() -> tuple[type[BaseException], ...]:
    """Exceptions that mean "bad input": the CLI prints them as one line and exits 2."""
    from mimicrete import LogFormatError

    return (UsageError, LogFormatError, FileNotFoundError, IsADirectoryError, NotADirectoryError)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    mod = importlib.import_module(args._module)
    try:
        return int(mod.main(args) or 0)
    except KeyboardInterrupt:
        print(f"mimicrete {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # `mimicrete inspect ... | head`
        sys.stderr.close()
        return 0
    except Exception as e:
        if args.debug:
            raise
        code = 2 if isinstance(e, user_errors()) else 1
        print(f"mimicrete {args.command}: error: {e}", file=sys.stderr)
        return code


if __name__ == "__main__":
    sys.exit(main())
