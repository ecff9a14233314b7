"""mimicrete: hand demonstrations to robot skills.

Grouped by pipeline stage (hand → gesture → frame → IK → sim → demo → trainer):
``hands`` (joint layouts, the hand model, hand logs), ``gestures`` (SVM gesture models),
``kin`` (UR kinematics, hand frame → tool0 target), ``envs`` (gymnasium environments over the Rust
simulator), ``teleop`` (the per-frame session, ``convert``, the scripted demonstrator, the live
server), ``demos`` (MCAP demonstrations), ``learn`` (BC + GAIL + PPO trainer, evaluation),
``experiments`` (the sweep and its report), ``cli``.
"""

from __future__ import annotations

import os as _os
import signal as _signal
import sys as _sys


def _started_as_the_cli() -> bool:
    """True while this package is imported by the ``mimicrete`` command (the console script or
    ``python -m mimicrete``), before any of the command's code runs."""
    argv = getattr(_sys, "orig_argv", [])
    return (len(argv) >= 3 and argv[1] == "-m" and argv[2] == "mimicrete") or (
        len(argv) >= 2 and _os.path.basename(argv[1]) == "mimicrete"
    )


if _started_as_the_cli() and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:
    # Ctrl-C during the imports below (gymnasium takes a while) ends the command quietly, exit
    # 130; `mimicrete.cli.main` takes over from here (KeyboardInterrupt once the command runs)
    def _interrupted(signum: int, frame: object) -> None:
        try:
            _os.write(2, b"mimicrete: interrupted\n")
        finally:
            _os._exit(130)

    _signal.signal(_signal.SIGINT, _interrupted)

# `envs` registers mimicrete/TileSuction-v0, BlockGrip-v0 and Screw-v0 with gymnasium on import.
from mimicrete import _native, envs  # noqa: E402, F401
from mimicrete._native import (  # noqa: E402
    ActionShapeError,
    IkError,
    IoError,
    LogFormatError,
    MimicreteError,
    SimError,
    SimInputError,
)

__version__: str = _native.__version__

# Every exception mimicrete defines is a MimicreteError (the native ones above; the Python ones,
# e.g. ``learn.ConfigError``, beside the code that raises them); those a caller may also catch as
# ValueError / OSError / RuntimeError / FileNotFoundError stay subclasses of those too.
__all__ = [
    "ActionShapeError",
    "IkError",
    "IoError",
    "LogFormatError",
    "MimicreteError",
    "SimError",
    "SimInputError",
    "__version__",
]


def __getattr__(name: str):  # lazy submodules: `mc.kin`, `mc.envs`, ... import on first use
    import importlib

    if name in {
        "kin",
        "envs",
        "demos",
        "hands",
        "gestures",
        "teleop",
        "learn",
        "experiments",
        "cli",
        "tasks",
    }:
        return importlib.import_module(f"mimicrete.{name}")
    raise AttributeError(f"module 'mimicrete' has no attribute {name!r}")
