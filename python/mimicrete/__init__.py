"""mimicrete: hand demonstrations to robot skills.

Grouped by pipeline stage (hand → gesture → frame → IK → sim → demo → trainer):
``hands`` (joint layouts, the hand model, hand logs), ``gestures`` (SVM gesture models),
``kin`` (UR kinematics, hand frame → tool0 target), ``envs`` (gymnasium environments over the Rust
simulator), ``teleop`` (the per-frame session, ``convert``, the scripted demonstrator, the live
server), ``demos`` (MCAP demonstrations), ``learn`` (BC + GAIL + PPO trainer, evaluation),
``experiments`` (the sweep and its report), ``cli``.
"""

from __future__ import annotations

# `envs` registers mimicrete/TileSuction-v0, BlockGrip-v0 and Screw-v0 with gymnasium on import.
from mimicrete import _native, envs  # noqa: F401
from mimicrete._native import IkError, LogFormatError, MimicreteError, SimError

__version__: str = _native.__version__

__all__ = ["IkError", "LogFormatError", "MimicreteError", "SimError", "__version__"]


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
