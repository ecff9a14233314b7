"""The trainer: BC + GAIL + PPO with Unity ML-Agents' semantics (torch, CPU), evaluation, plots.

    >>> from mimicrete import learn
    >>> cfg, path = learn.config.resolve("configs/group3.yaml", seed=0)
    >>> trainer = learn.train(cfg, "runs/group3-seed0")          # the run dir is written as it goes
    >>> learn.evaluate_run("runs/group3-seed0", episodes=100)    # Table 5's row, eval.json

Modules, by what they own: ``config`` (the YAML schema), ``env`` (which env an id names),
``demo_data`` (demos as the trainer reads them), ``episodes`` (episode statistics), ``networks``,
``normalizer``, ``buffer`` (rollout, GAE), ``ppo``, ``gail``, ``bc``, ``run_state`` (what a run
changes), ``update`` (one update, read top to bottom), ``trainer`` (the update's fixed setup,
summaries, checkpoints), ``checkpoint`` (what a checkpoint holds), ``loop`` (a run: resume,
summaries, checkpoints), ``run_files`` (what a run dir holds), ``evaluate``, ``video`` (rollout
videos), ``plots``. The numpy toy env of the tests and smoke runs (env ids ``Toy…``) is
``mimicrete.testing.toyenv``. The names below are imported on first use, so importing the package
does not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "train": ("loop", "train"),
    "Trainer": ("trainer", "Trainer"),
    "NonFiniteLossError": ("update", "NonFiniteLossError"),
    "ResumeError": ("checkpoint", "ResumeError"),
    "evaluate_run": ("evaluate", "evaluate_run"),
    "format_row": ("evaluate", "format_row"),
    "format_rows": ("evaluate", "format_rows"),
    "learning_curves": ("plots", "learning_curves"),
    "read_scalars": ("run_files", "read_scalars"),
    "ConfigError": ("config", "ConfigError"),
    "DemoDataError": ("demo_data", "DemoDataError"),
    "RunDirError": ("run_files", "RunDirError"),
    "ensure_demos": ("demo_data", "ensure_demos"),
    "ensure_generated_demos": ("demo_data", "ensure_generated_demos"),
}

_SUBMODULES = {
    "bc", "buffer", "checkpoint", "config", "demo_data", "env", "episodes", "evaluate", "gail",
    "loop", "networks", "normalizer", "plots", "ppo", "run_files", "run_state",
    "trainer", "update", "video",
}  # fmt: skip

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        module, attr = _EXPORTS[name]
        return getattr(importlib.import_module(f"{__name__}.{module}"), attr)
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
