"""Our learner and the paper's recipe in the peers' grid (``peers run --methods ours paper``):
trained on the same first N demos the peers get, evaluated on the same start sets, written as
the same result files, so ``peers report`` puts all four methods in one table and one figure.

- ``ours``: what does best on the wide starts (``docs/wide_starts.md``). ``mimicrete demogen``
  turns the N demos into ``--gen-count`` demos at the wide starts (generation seed = the
  training seed), then ``mimicrete train`` runs ``configs/wide_gen1.yaml`` on them for one source
  demo and ``configs/wide_gen5.yaml`` for more (each config's own budget, 2M and 1M env steps,
  no early stop).
- ``paper``: the paper's recipe, group 4's config (PPO + GAIL + BC, ``configs/group4.yaml``) on
  the N demos themselves (``demo_episodes`` N), for ``--paper-steps`` env steps (1M: group 4 on
  the 60 demos installs 100 % from training starts within 1M on 3 of 3 seeds).

Both run as ``mimicrete`` subprocesses of this interpreter (our venv) under ``nice``, one at a
time; the evaluation is ``mimicrete eval`` (deterministic, env seed = training seed + 10,000, as
the peers'). A finished training (its record) or evaluation (its result file) is reused.
"""

from __future__ import annotations

import json
import re
import shutil
import sys
from pathlib import Path
from typing import Any

from .peers_report import PeersError

#: our learner's config by number of source demos (``None``: any other count)
OURS_CONFIG = {1: "configs/wide_gen1.yaml", None: "configs/wide_gen5.yaml"}
PAPER_CONFIG = "configs/group4.yaml"
DEFAULT_PAPER_STEPS = 1_000_000
DEFAULT_GEN_COUNT = 500
#: ``mimicrete eval --starts`` value and the file it writes, per start set
EVAL_FILES = {"training": "eval.json", "robust": "eval_robust.json", "wide": "eval_wide.json"}
_TRAINED = re.compile(r"trained (\d+) steps in (\d+) s")


def _mimicrete(*args: str) -> list[str]:
    return [sys.executable, "-m", "mimicrete", *args]


def config_of(method: str, n: int, repo: Path) -> Path:
    if method == "paper":
        return repo / PAPER_CONFIG
    return repo / OURS_CONFIG.get(n, OURS_CONFIG[None])


def train_cmds(
    method: str, demos: Path, run_dir: Path, gen_dir: Path, n: int, seed: int, repo: Path,
    steps: int | None, gen_count: int, converge: bool = False,
) -> list[list[str]]:  # fmt: skip
    """The commands that train ``method`` on the ``n`` demos in ``demos`` into ``run_dir``
    (``converge``: stop once training has converged, ``mimicrete train --stop-on-convergence``)."""
    common = ["--seed", str(seed), "--run-dir", str(run_dir), "--eval-episodes", "0",
              "--no-progress", "--force"]  # fmt: skip
    if converge:
        common.append("--stop-on-convergence")
    budget = [] if steps is None else ["--max-steps", str(steps)]
    cfg = str(config_of(method, n, repo))
    if method == "paper":
        return [
            _mimicrete("train", "--config", cfg, "--demos", str(demos),
                       "--set", f"behavior.demo_episodes={n}", *budget, *common)
        ]  # fmt: skip
    return [
        _mimicrete("demogen", "--demos", str(demos), "--source-count", str(n), "--count",
                   str(gen_count), "--starts", "wide", "--out", str(gen_dir), "--seed", str(seed),
                   "--no-progress"),
        _mimicrete("train", "--config", cfg, "--demos", str(gen_dir), *budget, *common),
    ]  # fmt: skip


def train(
    run_child: Any, method: str, demos: Path, out: Path, n: int, seed: int, repo: Path,
    steps: int | None, gen_count: int, nice: int, converge: bool = False,
) -> dict[str, Any]:  # fmt: skip
    """Train ``method`` on the first ``n`` demos (the folder ``demos``) into
    ``out/train/<method>-n<n>`` (once); its record. ``run_child`` is ``peers._run_child``."""
    run_dir = out / "train" / f"{method}-n{n}"
    record = run_dir.with_suffix(".json")
    if record.exists():
        rec = json.loads(record.read_text())
        if (
            rec.get("budget_asked") == steps
            and rec.get("gen_count") == (gen_count if method == "ours" else None)
            and rec.get("stop_on_convergence", False) == converge
        ):
            return rec
    gen_dir = out / "gen" / f"n{n}"
    for d in (run_dir, gen_dir if method == "ours" else None):
        if d is not None and d.exists():  # unfinished, or of another budget
            shutil.rmtree(d)
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    cmds = train_cmds(method, demos, run_dir, gen_dir, n, seed, repo, steps, gen_count, converge)
    gen_wall = gen_cpu = 0.0
    if len(cmds) == 2:
        gen_wall, gen_cpu = run_child(cmds[0], out / "train" / f"ours-n{n}-demogen.log", 1, nice)
    log = out / "train" / f"{method}-n{n}.log"
    wall, cpu = run_child(cmds[-1], log, 1, nice)
    found = _TRAINED.findall(log.read_text(errors="replace"))
    if not found:
        raise PeersError(f"{log}: no 'trained N steps in S s' line")
    env_steps, train_s = (int(x) for x in found[-1])
    rec = {
        "method": method,
        "demos": n,
        "steps": env_steps,
        "batch_size": None,
        "epochs": None,
        "budget_asked": steps,
        "stop_on_convergence": converge,
        "config": str(config_of(method, n, repo).relative_to(repo)),
        "gen_count": gen_count if method == "ours" else None,
        "gen_wall_s": round(gen_wall, 1),
        "gen_cpu_s": round(gen_cpu, 1),
        "seed": seed,
        "threads": 1,
        "train_wall_s": float(train_s),
        "train_process_wall_s": round(wall, 1),
        "train_cpu_s": round(cpu, 1),
        "command": " && ".join(" ".join(["mimicrete", *c[3:]]) for c in cmds),
    }
    from mimicrete.learn.run_files import atomic_write

    atomic_write(record, json.dumps(rec, indent=1))  # whole or absent: Ctrl-C leaves no half record
    return rec


def evaluate(
    run_child: Any, run_dir: Path, starts: str, episodes: int, nice: int
) -> dict[str, Any]:
    """``mimicrete eval`` of ``run_dir`` on ``starts`` (deterministic, the run's eval seed)."""
    log = run_dir.parent / f"{run_dir.name}-eval-{starts}.log"
    cmd = _mimicrete("eval", str(run_dir), "--episodes", str(episodes), "--starts", starts)
    wall, cpu = run_child(cmd, log, 1, nice)
    res = json.loads((run_dir / EVAL_FILES[starts]).read_text())
    keep = ("episodes", "installed_rate", "picked_rate", "mean_episode_length", "seed")
    out = {k: res[k] for k in keep}
    out["eval_seed"] = out.pop("seed")
    out.update(starts=starts, eval_wall_s=round(wall, 1), eval_cpu_s=round(cpu, 1))
    out["eval_command"] = " ".join(["mimicrete", *cmd[3:]])
    return out
