"""The paper's experiments as a Ray Tune sweep: Table 3's nine groups x seeds, one run each.

``python -m mimicrete.experiments`` (what ``make experiments`` runs) does, in order:

1. makes sure the demonstrations exist (``mimicrete synth-hands`` + ``mimicrete convert`` into the
   configs' demo dir when it holds too few episodes);
2. runs a ``ray.tune.Tuner`` with a grid over ``group`` x ``seed``; each trial trains one run of
   ``configs/group<g>.yaml`` with that seed in its own run dir ``<out>/runs/group<g>-seed<s>`` and
   evaluates it (``eval.json``, 100 episodes); 1 CPU per trial by default;
3. writes ``<out>/sweep.json`` (every trial's status and error) and, unless ``--no-report``, the
   results report (``mimicrete.report``: ``docs/RESULTS.md`` + ``docs/figures/``).

Local by default (``ray.init(num_cpus=--num-cpus)``); ``--address`` joins an existing cluster (then
every node must see ``--out`` at the same path, e.g. a shared file system).

Resuming: the Tune experiment state lives in ``<out>/tune/<name>``; running the same command again
after an interruption restores it (``Tuner.restore``, unfinished trials resumed; ``--retry-errored``
also restarts crashed ones). Inside a trial, a run dir that already has trainer checkpoints is
continued with the trainer's ``--resume`` (exact resume from the last checkpoint); a run dir whose
``trial.json`` says ``done`` is not trained again. A crashed trial writes its traceback into its
``trial.json`` before Tune records it as errored, so the report lists it.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import socket
import sys
import time
import traceback
from pathlib import Path
from typing import Any

GROUPS = tuple(range(1, 10))  # Table 3
DEFAULT_SEEDS = (0, 1, 2)
DEFAULT_MAX_STEPS = 1_000_000  # docs/RESULTS.md: 27 trials in ~2 h on 2 cores (paper: 5M)
DEFAULT_OUT = "runs/experiments"
DEFAULT_NAME = "table3"
TRIAL_FILE = "trial.json"
SWEEP_FILE = "sweep.json"
RUN_DIR_RE = re.compile(r"^group(\d+)-seed(\d+)$")


def repo_root() -> Path:
    return Path(__file__).resolve().parents[2]


def run_dir_name(group: int, seed: int) -> str:
    return f"group{group}-seed{seed}"


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
# trial.json: what happened to one run dir (written by the trial, read by the report)
# ----------------------------------------------------------------------------------------------


def read_trial(run_dir: Path) -> dict[str, Any]:
    p = Path(run_dir) / TRIAL_FILE
    if not p.exists():
        return {}
    try:
        return json.loads(p.read_text())
    except json.JSONDecodeError:
        return {}


def write_trial(run_dir: Path, meta: dict[str, Any]) -> None:
    p = Path(run_dir) / TRIAL_FILE
    tmp = p.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(meta, indent=1))
    os.replace(tmp, p)


# ----------------------------------------------------------------------------------------------
# one trial = one training run (the trainer's programmatic API, see learn/train.py)
# ----------------------------------------------------------------------------------------------


def _config_path(config_dir: str, group: int) -> Path:
    return Path(config_dir) / f"group{group}.yaml"


def train_one(
    *,
    group: int,
    seed: int,
    config_dir: str,
    run_root: str,
    max_steps: int,
    demos: str | None = None,
    num_envs: int | None = None,
    overrides: list[str] | None = None,
    eval_episodes: int = 100,
) -> dict[str, Any]:
    """Train (or continue, or skip when done) group ``group`` with ``seed`` in
    ``run_root/group<g>-seed<s>``; evaluate; return the final metrics. This is the adapter onto
    ``mimicrete.learn.train.train`` (the same steps as ``mimicrete train`` + ``mimicrete eval``).
    Exceptions propagate after being recorded in ``trial.json``."""
    import torch

    from mimicrete.learn import config as config_mod
    from mimicrete.learn import evaluate, plots
    from mimicrete.learn import train as train_mod

    run_dir = Path(run_root) / run_dir_name(group, seed)
    run_dir.mkdir(parents=True, exist_ok=True)
    meta = read_trial(run_dir)
    if meta.get("max_steps") not in (None, max_steps):
        # the schedules decay over max_steps: a run dir cannot change budget half way
        raise ValueError(
            f"{run_dir} was trained with max_steps {meta['max_steps']}, this sweep asks for "
            f"{max_steps}: use another --out"
        )
    if meta.get("status") == "done" and (eval_episodes <= 0 or (run_dir / "eval.json").exists()):
        return _metrics(run_dir, meta)

    resume = train_mod.latest_checkpoint(run_dir) is not None
    meta.update(
        group=group,
        seed=seed,
        config=str(_config_path(config_dir, group)),
        max_steps=max_steps,
        status="running",
        host=socket.gethostname(),
        attempts=int(meta.get("attempts", 0)) + 1,
        resumed_from_checkpoint=bool(meta.get("resumed_from_checkpoint")) or resume,
        error=None,
    )
    segments = list(meta.get("segments", []))
    if segments and segments[-1].get("seconds") is None:
        # the previous attempt was killed (e.g. the sweep was interrupted): its end is estimated
        # from the last write into the run dir (scalars.csv is appended at every summary)
        last = max(
            (
                p.stat().st_mtime
                for p in (run_dir / "scalars.csv", run_dir / TRIAL_FILE)
                if p.exists()
            ),
            default=segments[-1]["start"],
        )
        segments[-1]["seconds"] = max(0.0, last - segments[-1]["start"])
        segments[-1]["estimated"] = True
    t0 = time.time()
    segments.append({"start": t0, "seconds": None, "resumed": resume})
    meta["segments"] = segments
    write_trial(run_dir, meta)

    def _close_segment(status: str, error: str | None) -> None:
        segments[-1]["seconds"] = time.time() - t0
        meta["segments"] = segments
        meta["wall_clock_s"] = float(sum(s["seconds"] or 0.0 for s in segments))
        meta["status"] = status
        meta["error"] = error
        write_trial(run_dir, meta)

    try:
        cfg = config_mod.load(_config_path(config_dir, group))
        ov = list(overrides or [])
        ov.append(f"env_settings.seed={seed}")
        ov.append(f"behavior.max_steps={max_steps}")
        if num_envs is not None:
            ov.append(f"env_settings.num_envs={num_envs}")
        cfg = config_mod.with_overrides(cfg, ov)
        torch.set_num_threads(max(1, cfg.torch_settings.num_threads))
        if demos is None and cfg.demo_path and not Path(cfg.demo_path).is_absolute():
            # Tune runs a trial in its own working dir: a relative demo_path means the repo's
            demos = str(repo_root() / cfg.demo_path)
        tr = train_mod.train(cfg, run_dir, demos=demos, resume=resume, progress=False)
        meta["final_step"] = int(tr.step)
        plots.learning_curves(run_dir)
        if eval_episodes > 0:
            evaluate.evaluate_run(run_dir, eval_episodes)
    except BaseException as e:  # recorded, then re-raised so Tune marks the trial errored
        _close_segment("error", "".join(traceback.format_exception(e)))
        raise
    _close_segment("done", None)
    return _metrics(run_dir, meta)


def _metrics(run_dir: Path, meta: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {
        "group": meta.get("group"),
        "seed": meta.get("seed"),
        "final_step": meta.get("final_step"),
        "wall_clock_s": meta.get("wall_clock_s"),
        "run_dir": str(run_dir),
    }
    ev = Path(run_dir) / "eval.json"
    if ev.exists():
        e = json.loads(ev.read_text())
        for k in ("picked_rate", "installed_rate", "mean_episode_length"):
            out[k] = e.get(k)
    return out


def tune_trainable(config: dict[str, Any]) -> None:
    """The function trainable: one training run, its final metrics reported once."""
    from ray import tune

    metrics = train_one(**config)
    tune.report({k: v for k, v in metrics.items() if v is not None})


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


def count_demo_episodes(path: Path) -> int:
    if path.is_file():
        return 1 if path.suffix in (".mcap", ".npz") else 0
    if not path.is_dir():
        return 0
    return len(list(path.glob("*.mcap")))


def ensure_demos(demo_dir: Path, episodes: int, seed: int = 0) -> Path:
    """Synthesise hand logs and convert them to MCAP demos when ``demo_dir`` holds fewer than
    ``episodes`` episodes (``mimicrete synth-hands`` then ``mimicrete convert``)."""
    from mimicrete import cli

    have = count_demo_episodes(demo_dir)
    if demo_dir.suffix == ".npz" or have >= episodes:
        return demo_dir
    hand_dir = demo_dir.parent / f"{demo_dir.name}_handlogs"
    n = max(episodes, 60)
    print(f"demos: {demo_dir} has {have} episodes, making {n} (synth-hands + convert)", flush=True)
    rc = cli.main(
        [
            "synth-hands",
            "--task",
            "suction",
            "--episodes",
            str(n),
            "--seed",
            str(seed),
            "--out",
            str(hand_dir),
        ]
    )
    if rc:
        raise RuntimeError(f"mimicrete synth-hands exited {rc}")
    rc = cli.main(
        ["convert", str(hand_dir), "--task", "suction", "--out", str(demo_dir), "--no-progress"]
    )
    if rc:
        raise RuntimeError(f"mimicrete convert exited {rc}")
    got = count_demo_episodes(demo_dir)
    if got < episodes:
        raise RuntimeError(f"{demo_dir}: {got} demo episodes after convert, need {episodes}")
    return demo_dir


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
        "overrides": list(args.set),
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
            print(f"warning: {_config_path(str(config_dir), g)} does not exist", file=sys.stderr)
    if not args.skip_demos:
        need = demos_needed_safe(config_dir, groups)
        if args.demos:
            need = {Path(args.demos): max(need.values(), default=0)} if need else {}
        for path, n in need.items():
            try:
                ensure_demos(path, n)
            except Exception as e:  # noqa: BLE001 - the groups that need them crash, reported
                print(f"warning: could not make demos in {path}: {e}", file=sys.stderr)

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
            print(
                f"resuming the sweep in {exp_dir} (its original groups, seeds and flags apply; "
                "--fresh starts a new one)",
                flush=True,
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


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m mimicrete.experiments",
        description="Table 3's groups x seeds as a Ray Tune sweep, then docs/RESULTS.md.",
    )
    p.add_argument("--groups", default="1-9", help="groups of Table 3, e.g. 1-9 or 1,2,4 (1-9)")
    p.add_argument(
        "--seeds", type=int, nargs="+", default=list(DEFAULT_SEEDS), help="seeds per group (0 1 2)"
    )
    p.add_argument(
        "--max-steps",
        type=int,
        default=DEFAULT_MAX_STEPS,
        help=f"env steps per trial ({DEFAULT_MAX_STEPS}; the paper: 5000000)",
    )
    p.add_argument(
        "--config-dir",
        default=str(repo_root() / "configs"),
        help="where group<g>.yaml live (configs/)",
    )
    p.add_argument("--demos", help="demo dir for every group (default: each config's demo_path)")
    p.add_argument("--skip-demos", action="store_true", help="do not create missing demos")
    p.add_argument("--num-envs", type=int, help="override env_settings.num_envs")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="config override passed to every trial (repeatable)",
    )
    p.add_argument("--eval-episodes", type=int, default=100, help="evaluation episodes (100)")
    p.add_argument("--out", default=DEFAULT_OUT, help=f"run root ({DEFAULT_OUT})")
    p.add_argument("--name", default=DEFAULT_NAME, help=f"Tune experiment name ({DEFAULT_NAME})")
    p.add_argument("--address", help="an existing Ray cluster (e.g. auto or ray://host:10001)")
    p.add_argument(
        "--num-cpus",
        type=int,
        default=os.cpu_count() or 1,
        help="CPUs of the local Ray instance (all)",
    )
    p.add_argument("--cpus-per-trial", type=float, default=1.0, help="CPUs per trial (1)")
    p.add_argument("--max-concurrent", type=int, default=0, help="trials at once (0: by CPUs)")
    p.add_argument(
        "--max-failures",
        type=int,
        default=0,
        help="Tune retries of a crashed trial (0; a retry resumes the run dir)",
    )
    p.add_argument(
        "--retry-errored", action="store_true", help="on resume, also rerun trials that crashed"
    )
    p.add_argument(
        "--fresh",
        action="store_true",
        help="start a new Tune experiment even if one can be restored",
    )
    p.add_argument("--no-report", action="store_true", help="do not write the report")
    p.add_argument(
        "--report-out",
        default=str(repo_root() / "docs" / "RESULTS.md"),
        help="report path (docs/RESULTS.md; figures go to its dir/figures)",
    )
    p.add_argument("--quiet", action="store_true", help="less Ray/Tune output")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        summary = run_sweep(args)
    except KeyboardInterrupt:
        print("interrupted: run the same command again to resume the sweep", file=sys.stderr)
        return 130
    for t in summary["trials"]:
        line = f"group {t['group']} seed {t['seed']}: {t['status']}"
        if t["error"]:
            line += f" ({t['error'].splitlines()[0][:200]})"
        print(line)
    if not args.no_report:
        from mimicrete import report

        out = Path(args.report_out)
        report.write_report(
            Path(args.out) / "runs",
            out,
            out.parent / "figures",
            sweep_file=Path(args.out) / SWEEP_FILE,
        )
        print(f"wrote {out}")
    unfinished = summary.get("sweeps", [summary])[-1]["unfinished"]  # this sweep's own trials
    if unfinished:
        # Tune caught the Ctrl-C itself and returned: still an interrupted sweep
        print(
            f"interrupted: {unfinished} trial(s) unfinished; run the same command "
            "again to resume the sweep",
            file=sys.stderr,
        )
        return 130
    return 1 if summary["errors"] and summary["errors"] == len(summary["trials"]) else 0


if __name__ == "__main__":
    sys.exit(main())
