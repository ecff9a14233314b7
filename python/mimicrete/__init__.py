"""mimicrete: hand demonstrations to robot skills.

Submodules: ``kin`` (UR kinematics), ``envs`` (gymnasium environments over the Rust simulator),
``demos`` (MCAP demonstrations), ``gestures`` (SVM gesture models), ``synth`` (scripted hand
demonstrator), ``convert`` (hand log -> demo), ``learn`` (BC + GAIL + PPO trainer), ``cli``.
"""

from __future__ import annotations

# `envs` registers mimicrete/TileSuction-v0, BlockGrip-v0 and Screw-v0 with gymnasium on import.
from mimicrete import _native, envs  # noqa: F401
from mimicrete._native import IkError, LogFormatError, MimicreteError, SimError

__version__: str = _native.__version__

__all__ = ["IkError", "LogFormatError", "MimicreteError", "SimError", "__version__"]


def __getattr__(name: str):  # lazy submodules: `mc.kin`, `mc.envs`, ... import on first use
    import importlib

    if name in {"kin", "envs", "demos", "gestures", "synth", "convert", "learn", "cli", "handlog"}:
        return importlib.import_module(f"mimicrete.{name}")
    raise AttributeError(f"module 'mimicrete' has no attribute {name!r}")
