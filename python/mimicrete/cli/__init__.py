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
import contextlib
import importlib
import io
import os
import signal
import sys
import threading
from typing import Any

from mimicrete._native import MimicreteError

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
    "demogen": ("demogen", "generate installing demos at new starts from a few (MimicGen)"),
    "inspect": ("inspect", "show what is in an MCAP demo and check it"),
    "export": ("export", "MCAP demos -> a LeRobot v3.0 or Minari dataset (one task per dataset)"),
    "deploy": (
        "deploy",
        "a trained policy on a robot: --sim, --shadow (reads a UR, sends nothing) or --live",
    ),
}


class UsageError(MimicreteError):
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


def calibration_arg(path: str | None):  # -> Calibration | None
    """The calibration a ``--calibration FILE.json`` flag names (``Calibration.to_dict``'s JSON,
    as a recentre saves it), parsed and checked (None: no flag); a file that is missing or not a
    calibration is a :class:`UsageError` naming the flag."""
    if not path:
        return None
    import json

    from mimicrete import LogFormatError
    from mimicrete.kin import parse_calibration

    try:
        with open(path, encoding="utf-8") as f:
            return parse_calibration(json.load(f), path, None, "calibration")
    except (OSError, ValueError, LogFormatError) as e:
        raise UsageError(f"--calibration {path}: {getattr(e, 'strerror', None) or e}") from None


def task_file_arg(path: str, task: str | None) -> str:
    """The task (``suction`` | ``grip`` | ``screw`` | ``row``) the spec file at ``path`` runs,
    the file read and checked; a bad or unreadable spec, or one of another task than ``--task``,
    is a :class:`UsageError` naming the file (and the field, the value and why)."""
    from mimicrete import tasks
    from mimicrete._native import SimInputError

    try:
        spec_task, _ = tasks.load_task_file(path)
    except (SimInputError, OSError) as e:
        raise UsageError(f"--task-file {tasks.task_file_error(path, e)}") from None
    if task is not None and tasks.get(task).name != spec_task.name:
        raise UsageError(
            f"--task-file {path} runs the {spec_task.name} task ({spec_task.sim}), "
            f"not --task {task}"
        )
    return spec_task.name


def user_errors() -> tuple[type[BaseException], ...]:
    """Exceptions that mean "bad input": the CLI prints them as one line and exits 2 (a task a
    part of the package is not built for, :class:`mimicrete.tasks.NotBuiltError`, too)."""
    from mimicrete import LogFormatError
    from mimicrete.tasks import NotBuiltError

    return (
        UsageError,
        LogFormatError,
        NotBuiltError,
        FileNotFoundError,
        IsADirectoryError,
        NotADirectoryError,
    )


#: characters of an error message printed (a message quoting a huge value is cut)
MAX_MESSAGE = 600


def bounded(message: str, limit: int = MAX_MESSAGE) -> str:
    """``message`` on one line, at most ``limit`` characters (the cut is said)."""
    one = " ".join(message.split("\n")) if "\n" in message else message
    if len(one) <= limit:
        return one
    return f"{one[: limit - 40]}... ({len(one) - limit + 40} more characters)"


def _quiet_interrupt(signum: int, frame: object) -> None:
    """Ctrl-C while the command starts or ends (imports, parsing, --help, the interpreter's
    exit): nothing to clean up, so exit 130 at once, without a traceback."""
    try:
        os.write(2, b"mimicrete: interrupted\n")
    finally:
        os._exit(130)


class _Stdout(io.TextIOBase):
    """``sys.stdout`` that survives its reader going away (``mimicrete convert DIR | head -1``):
    once the pipe is closed, output goes to /dev/null and the command carries on to the end, so a
    closed stdout never stops the work half way."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.closed_pipe = False

    def _drop(self) -> None:
        if not self.closed_pipe:
            self.closed_pipe = True
            try:  # the interpreter's own final flush of fd 1 must not fail either
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, self.inner.fileno())
                os.close(devnull)
            except (OSError, ValueError, io.UnsupportedOperation):
                pass

    def write(self, s: str) -> int:
        if not self.closed_pipe:
            try:
                return self.inner.write(s)
            except BrokenPipeError:
                self._drop()
        return len(s)

    def flush(self) -> None:
        if not self.closed_pipe:
            try:
                self.inner.flush()
            except BrokenPipeError:
                self._drop()

    def isatty(self) -> bool:
        return not self.closed_pipe and self.inner.isatty()

    def fileno(self) -> int:
        return self.inner.fileno()

    @property
    def encoding(self) -> str:  # type: ignore[override]
        return getattr(self.inner, "encoding", "utf-8")

    def writable(self) -> bool:
        return True


def main(argv: list[str] | None = None, *, program: bool | None = None) -> int:
    """The program (``argv`` None: ``sys.argv``; the console script, ``python -m mimicrete``,
    ``python train.py`` with ``program=True``) or one command called from Python (``argv``
    given: SIGINT's handler is left alone)."""
    entry = (
        (program if program is not None else argv is None)
        and threading.current_thread() is threading.main_thread()
        and signal.getsignal(signal.SIGINT) is not signal.SIG_IGN  # started with Ctrl-C off
    )
    if entry:
        signal.signal(signal.SIGINT, _quiet_interrupt)
    old_stdout = sys.stdout
    guard = _Stdout(old_stdout) if old_stdout is not None else None
    if guard is not None:
        sys.stdout = guard
    try:
        return _main(argv, entry)
    finally:
        if guard is not None and sys.stdout is guard:
            with contextlib.suppress(Exception):
                guard.flush()
            sys.stdout = old_stdout
        if entry:  # the interpreter's exit (joining threads, flushing) is quiet on Ctrl-C too
            signal.signal(signal.SIGINT, _quiet_interrupt)


def _main(argv: list[str] | None, entry: bool) -> int:
    command = "(starting)"
    args: argparse.Namespace | None = None
    try:
        args = build_parser().parse_args(argv)
        command = args.command
        mod = importlib.import_module(args._module)
        if entry:  # from here on Ctrl-C is a KeyboardInterrupt: the command cleans up
            signal.signal(signal.SIGINT, signal.default_int_handler)
        return int(mod.main(args) or 0)
    except KeyboardInterrupt:
        if entry:
            signal.signal(signal.SIGINT, _quiet_interrupt)
        print(f"mimicrete {command}: interrupted", file=sys.stderr)
        return 130
    except Exception as e:
        if args is None or args.debug:  # the parser itself failed: a bug, show it
            raise
        code = 2 if isinstance(e, user_errors()) else 1
        print(f"mimicrete {command}: error: {bounded(str(e))}", file=sys.stderr)
        return code


if __name__ == "__main__":
    sys.exit(main())
