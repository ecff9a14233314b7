"""The paper's experiments as a Ray Tune sweep: Table 3's nine groups x seeds, one run each.

``python -m mimicrete.experiments`` (what ``make experiments`` runs; flags in ``__main__.py``)
does, in order:

1. makes sure the demonstrations exist (``mimicrete.learn.ensure_demos``: synth-hands + convert
   into the configs' demo dir when it holds too few episodes);
2. runs a ``ray.tune.Tuner`` with a grid over ``group`` x ``seed``; each trial
   (``trials.train_one``) trains one run of ``configs/group<g>.yaml`` with that seed in its own run
   dir ``<out>/runs/group<g>-seed<s>`` and evaluates it (``eval.json``, 100 episodes); 1 CPU per
   trial by default;
3. writes ``<out>/sweep.json`` (every trial's status and error) and, unless ``--no-report``, the
   results report (``report.py``: ``docs/RESULTS.md`` + ``docs/figures/``).

Local by default (``ray.init(num_cpus=--num-cpus)``); ``--address`` joins an existing cluster (then
every node must see ``--out`` at the same path, e.g. a shared file system).

Resuming: the Tune experiment state lives in ``<out>/tune/<name>``; running the same command again
after an interruption restores it (``Tuner.restore``, unfinished trials resumed; ``--retry-errored``
also restarts crashed ones). Inside a trial, a run dir that already has trainer checkpoints is
continued with the trainer's resume (exact resume from the last checkpoint); a run dir whose
``trial.json`` says ``done`` is not trained again. A crashed trial writes its traceback into its
``trial.json`` before Tune records it as errored, so the report lists it.
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import sys
import time
from pathlib import Path
from typing import Any

from mimicrete.learn.demo_data import ensure_demos

from .trials import _config_path, read_trial, repo_root, run_dir_name, tune_trainable

logger = logging.getLogger(__name__)

GROUPS = tuple(range(1, 10))  # Table 3
DEFAULT_SEEDS = (0, 1, 2)
DEFAULT_MAX_STEPS = 1_000_000  # docs/RESULTS.md: 27 trials in ~2 h on 2 cores (paper: 5M)
DEFAULT_OUT = "runs/experiments"
#: ``--stop-on-convergence``: the criterion of ``mimicrete train --stop-on-convergence``
CONVERGENCE_OVERRIDE = "behavior.stop_on_convergence={}"
NO_OVERLAP_OVERRIDE = "torch_settings.overlap_gail=false"
DEFAULT_NAME = "table3"
SWEEP_FILE = "sweep.json"


def parse_groups(spec: str) -> list[int]:
    """``"1-9"``, ``"1,2,4"``, ``"3-5,8"`` -> sorted unique group numbers."""
    out: set[int] = set()
    for part in spec.split(","):
        part = part.strip()
        if not part:
            continue
        if "-" in part:
            a, b = (int(x) for x in part.split("-", 1))
            if a > b:
                raise ValueError(f"bad group range {part!r}")
            out.update(range(a, b + 1))
        else:
            out.add(int(part))
    if not out:
        raise ValueError(f"no groups in {spec!r}")
    if min(out) < 1:
        raise ValueError(f"group numbers start at 1: {spec!r}")
    return sorted(out)


# ----------------------------------------------------------------------------------------------
# demos
# ----------------------------------------------------------------------------------------------


def demos_needed(config_dir: Path, groups: list[int]) -> dict[Path, int]:
    """Demo dir -> the most episodes any selected group needs from it (groups without GAIL/BC
    need none). Relative demo paths are relative to the repo root (as ``make`` runs there)."""
    from mimicrete.learn import config as config_mod

    need: dict[Path, int] = {}
    for g in groups:
        cfg = config_mod.load(_config_path(str(config_dir), g))
        b = cfg.behavior
        if b.reward_signals.gail is None and b.behavioral_cloning is None:
            continue
        p = cfg.demo_path
        if not p:
            continue
        path = Path(p) if Path(p).is_absolute() else repo_root() / p
        need[path] = max(need.get(path, 0), int(b.demo_episodes or 0))
    return need


# ----------------------------------------------------------------------------------------------
# the sweep
# ----------------------------------------------------------------------------------------------


def build_param_space(args: argparse.Namespace, groups: list[int], seeds: list[int]) -> dict:
    from ray import tune

    return {
        "group": tune.grid_search(groups),
        "seed": tune.grid_search(seeds),
        "config_dir": str(Path(args.config_dir).resolve()),
        "run_root": str((Path(args.out) / "runs").resolve()),
        "max_steps": int(args.max_steps),
        "demos": str(Path(args.demos).resolve()) if args.demos else None,
        "num_envs": args.num_envs,
        "overrides": list(args.set)
        + ([CONVERGENCE_OVERRIDE] if getattr(args, "stop_on_convergence", False) else [])
        # a trial given less than 2 CPUs keeps GAIL's steps on its own thread (no free core)
        + ([NO_OVERLAP_OVERRIDE] if float(getattr(args, "cpus_per_trial", 1.0)) < 2 else []),
        "eval_episodes": int(args.eval_episodes),
    }


def run_sweep(args: argparse.Namespace) -> dict[str, Any]:
    """Run (or resume) the sweep; returns the sweep summary also written to ``sweep.json``."""
    import ray
    from ray import tune

    groups = parse_groups(args.groups)
    seeds = sorted(set(args.seeds))
    config_dir = Path(args.config_dir)
    for g in groups:
        if not _config_path(str(config_dir), g).exists():
            # a missing config is not fatal for the sweep: that group's trials crash and are listed
            logger.warning("%s does not exist", _config_path(str(config_dir), g))
    if not args.skip_demos:
        need = demos_needed_safe(config_dir, groups)
        if args.demos:
            need = {Path(args.demos): max(need.values(), default=0)} if need else {}
        for path, n in need.items():
            try:
                ensure_demos(path, n)
            except Exception as e:  # noqa: BLE001 - the groups that need them crash, reported
                logger.warning("could not make demos in %s: %s", path, e)

    out = Path(args.out).resolve()
    storage = out / "tune"
    exp_dir = storage / args.name
    if args.address:
        ray.init(address=args.address, log_to_driver=not args.quiet)
    else:
        ray.init(num_cpus=args.num_cpus, include_dashboard=False, log_to_driver=not args.quiet)
    try:
        trainable = tune.with_resources(tune_trainable, {"cpu": args.cpus_per_trial})
        if not args.fresh and tune.Tuner.can_restore(str(exp_dir)):
            logger.info(
                "resuming the sweep in %s (its original groups, seeds and flags apply; --fresh "
                "starts a new one)",
                exp_dir,
            )
            tuner = tune.Tuner.restore(
                str(exp_dir),
                trainable,
                resume_unfinished=True,
                resume_errored=args.retry_errored,
                restart_errored=False,
            )
        else:
            tuner = tune.Tuner(
                trainable,
                param_space=build_param_space(args, groups, seeds),
                tune_config=tune.TuneConfig(max_concurrent_trials=args.max_concurrent or None),
                run_config=tune.RunConfig(
                    name=args.name,
                    storage_path=str(storage),
                    failure_config=tune.FailureConfig(
                        max_failures=args.max_failures, fail_fast=False
                    ),
                    verbose=0 if args.quiet else 1,
                ),
            )
        t0 = time.time()
        grid = tuner.fit()
        elapsed = time.time() - t0
    finally:
        ray.shutdown()
    summary = summarise(grid, elapsed, args, groups, seeds)
    previous = out / SWEEP_FILE
    if previous.exists():
        summary = merge_summaries(json.loads(previous.read_text()), summary)
    previous.write_text(json.dumps(summary, indent=1))
    return summary


def merge_summaries(old: dict[str, Any], new: dict[str, Any]) -> dict[str, Any]:
    """One ``sweep.json`` for every sweep run into the same ``--out``: e.g. groups 3 and 4 first,
    the other seven later, so that the report covers all nine. The same experiment (a resume)
    replaces its earlier summary; a different one adds its trials (a (group, seed) trained again
    takes the newer status), wall clock and command."""
    if old.get("name") == new.get("name") or "trials" not in old:
        return new
    parts = [p for p in old.get("sweeps", [old]) if p.get("name") != new.get("name")]
    parts.append({k: v for k, v in new.items() if k not in ("trials", "sweeps")})
    trials = {(t.get("group"), t.get("seed")): t for t in old["trials"]}
    trials.update({(t.get("group"), t.get("seed")): t for t in new["trials"]})
    merged_trials = sorted(trials.values(), key=lambda t: (t["group"] or 0, t["seed"] or 0))
    budgets = {p.get("max_steps") for p in parts}
    return {
        **new,
        "name": " + ".join(p["name"] for p in parts),
        "groups": sorted({g for p in parts for g in p.get("groups", [])}),
        "seeds": sorted({s for p in parts for s in p.get("seeds", [])}),
        "max_steps": new["max_steps"] if len(budgets) == 1 else None,
        "sweep_wall_clock_s": sum(p.get("sweep_wall_clock_s") or 0.0 for p in parts),
        "errors": sum(t["status"] == "error" for t in merged_trials),
        "unfinished": sum(t["status"] == "unfinished" for t in merged_trials),
        "trials": merged_trials,
        "command": " && ".join(p["command"] for p in parts),
        "sweeps": parts,
    }


def demos_needed_safe(config_dir: Path, groups: list[int]) -> dict[Path, int]:
    """``demos_needed`` over the groups whose configs load (a broken config is the trial's
    problem: it crashes there and is reported)."""
    ok = []
    from mimicrete.learn import config as config_mod

    for g in groups:
        try:
            config_mod.load(_config_path(str(config_dir), g))
            ok.append(g)
        except Exception:  # noqa: BLE001 - reported by the trial
            continue
    return demos_needed(config_dir, ok)


ANSI_RE = re.compile(r"\x1b\[[0-9;]*m")


def describe_error(err: BaseException) -> str:
    """``Type: message`` of the root cause (a ``RayTaskError`` wraps the trial's exception)."""
    cause = getattr(err, "cause", None) or err
    text = ANSI_RE.sub("", str(cause)).strip()
    lines = [ln for ln in text.splitlines() if ln.strip()]
    last = lines[-1] if lines else ""
    return f"{type(cause).__name__}: {last}"


def summarise(grid, elapsed: float, args, groups, seeds) -> dict[str, Any]:
    trials = []
    for i in range(len(grid)):
        r = grid[i]
        cfg = r.config or {}
        err = r.error
        meta = {}
        if cfg.get("run_root") and cfg.get("group") is not None and cfg.get("seed") is not None:
            meta = read_trial(Path(cfg["run_root"]) / run_dir_name(cfg["group"], cfg["seed"]))
        if err is not None:
            status = "error"
        elif meta.get("status") == "done" and r.metrics:
            status = "done"
        else:
            status = "unfinished"  # e.g. the sweep was interrupted; rerun the command to resume
        trials.append(
            {
                "group": cfg.get("group"),
                "seed": cfg.get("seed"),
                "status": status,
                "error": None if err is None else describe_error(err),
                "metrics": {
                    k: v
                    for k, v in (r.metrics or {}).items()
                    if k
                    in (
                        "picked_rate",
                        "installed_rate",
                        "mean_episode_length",
                        "final_step",
                        "wall_clock_s",
                    )
                },
                "trial_path": r.path,
            }
        )
    trials.sort(key=lambda t: (t["group"] or 0, t["seed"] or 0))
    return {
        "name": args.name,
        "groups": groups,
        "seeds": seeds,
        "max_steps": int(args.max_steps),
        "sweep_wall_clock_s": elapsed,
        "num_cpus": args.num_cpus,
        "address": args.address,
        "cpus_per_trial": args.cpus_per_trial,
        "errors": sum(t["status"] == "error" for t in trials),
        "unfinished": sum(t["status"] == "unfinished" for t in trials),
        "trials": trials,
        "command": " ".join(["python -m mimicrete.experiments", *sys.argv[1:]]),
    }
