"""The sweep's run directories read back: one :class:`Run` per ``group<g>-seed<s>/``.

Per run dir (written by ``mimicrete.experiments`` / ``mimicrete train``): ``scalars.csv``
(ML-Agents tag names, one row per summary, ``step`` first), ``eval.json`` (``mimicrete eval``:
picked_rate, installed_rate, mean_episode_length) and ``eval_stochastic.json`` (the same with the
policy sampled), ``trial.json`` (status, error, wall clock, budget) and ``run.json`` (max_steps,
the step where training converged). ``sweep.json`` beside the run dirs adds trials that crashed
before writing anything.
"""

from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete.learn.run_files import read_scalars

RUN_DIR_RE = re.compile(r"^group(\d+)-seed(\d+)$")


@dataclass
class Run:
    group: int
    seed: int
    path: Path | None
    status: str = "unknown"  # done | error | running | unknown
    error: str | None = None
    wall_clock_s: float | None = None
    max_steps: int | None = None
    final_step: int | None = None
    scalars: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    eval: dict[str, Any] | None = None
    eval_sampled: dict[str, Any] | None = None
    converged_at: int | None = None  # run.json's convergence.converged_at_step
    resolved: dict[str, Any] | None = None

    @property
    def name(self) -> str:
        return f"group{self.group}-seed{self.seed}"

    @property
    def behavior(self) -> dict[str, Any]:
        """The behavior section of the run's resolved config ({} without one)."""
        behaviors = (self.resolved or {}).get("behaviors") or {}
        return next(iter(behaviors.values()), None) or {}


def _json(path: Path) -> dict[str, Any] | None:
    try:
        return json.loads(path.read_text())
    except (FileNotFoundError, json.JSONDecodeError):
        return None


def load_run(path: Path, name_re: re.Pattern[str] = RUN_DIR_RE) -> Run | None:
    """The run in ``path`` if its name matches ``name_re`` (group and seed its first two groups)."""
    m = name_re.match(path.name)
    if not m or not path.is_dir():
        return None
    run = Run(int(m.group(1)), int(m.group(2)), path)
    trial = _json(path / "trial.json") or {}
    run.status = trial.get("status", "unknown")
    run.error = trial.get("error")
    run.wall_clock_s = trial.get("wall_clock_s")
    run.final_step = trial.get("final_step")
    info = _json(path / "run.json") or {}
    run.max_steps = trial.get("max_steps") or info.get("max_steps")
    run.converged_at = (info.get("convergence") or {}).get("converged_at_step")
    if (path / "scalars.csv").exists():
        run.scalars = read_scalars(path / "scalars.csv")
        if run.final_step is None:
            steps = [s[-1] for s, _ in run.scalars.values() if len(s)]
            run.final_step = int(max(steps)) if steps else None
    run.eval = _json(path / "eval.json")
    run.eval_sampled = _json(path / "eval_stochastic.json")
    if run.status == "unknown" and run.eval is not None:
        run.status = "done"
    rc = path / "resolved_config.yaml"
    if rc.exists():
        import yaml

        run.resolved = yaml.safe_load(rc.read_text())
    return run


def load_runs(
    run_root: Path | list[Path], sweep_file: Path | list[Path] | None = None
) -> list[Run]:
    """Every ``group<g>-seed<s>`` dir under ``run_root`` (or under each of a list of roots: a
    sweep run in parts with different budgets; a later root's run replaces an earlier one's of
    the same group and seed), plus the errored trials of ``sweep_file`` (or files) that left no
    run dir (or no error in it)."""
    roots = run_root if isinstance(run_root, list) else [run_root]
    runs: dict[tuple[int, int], Run] = {}
    for root in roots:
        if Path(root).is_dir():
            for p in sorted(Path(root).iterdir()):
                r = load_run(p)
                if r is not None:
                    runs[(r.group, r.seed)] = r
    files = sweep_file if isinstance(sweep_file, list) else [sweep_file] if sweep_file else []
    trials = [t for f in files for t in (_json(Path(f)) or {}).get("trials", [])]
    for t in trials:
        if t.get("group") is None or t.get("seed") is None:
            continue
        key = (int(t["group"]), int(t["seed"]))
        if t.get("status") == "error":
            r = runs.get(key) or Run(key[0], key[1], None)
            if r.status != "error" or not r.error:
                r.status = "error"
                r.error = r.error or t.get("error")
            runs[key] = r
    return [runs[k] for k in sorted(runs)]


def sweep_parts(runs: list[Run]) -> dict[tuple[str | None, int | None, bool], set[int]]:
    """Groups by (sweep out dir relative to the working dir, budget, stop on convergence)."""
    out: dict[tuple[str | None, int | None, bool], set[int]] = {}
    for run in runs:
        root = None
        if run.path is not None:
            root = os.path.relpath(run.path.parent.parent)
        key = (root, run.max_steps, bool(run.behavior.get("stop_on_convergence")))
        out.setdefault(key, set()).add(run.group)
    return out


def missing_dir(flag: str, dirs: list[str]) -> str | None:
    """The error line for the first of ``dirs`` (given as ``flag``) that is not a directory."""
    missing = [d for d in dirs if not Path(d).is_dir()]
    return f"{flag} {missing[0]}: no such directory" if missing else None
