"""``python -m mimicrete.experiments.demos_needed``: how many demonstrations our learner
(``configs/fewdemo.yaml``) needs, measured as issue 16 asks.

For each demo count (60, 20, 10, 5 by default) it makes that many demos of the task with a
scripted person's hands and the real teleoperation path (``synth-hands`` + ``convert``, seeds
other than ``make demos``' 60), trains the learner on them for each seed, and evaluates every run
the way the paper's groups are evaluated (100 deterministic episodes from the env's own starts),
plus a sampled evaluation, the robust starts (``mimicrete eval --robust``) and every checkpoint,
to find the first one that installs >= 97 % and the training's wall clock there. Runs already
evaluated are not run again (delete a run dir to redo it). Writes ``OUT/summary.json``, a Markdown
table ``OUT/summary.md`` and the figure ``OUT/installed_vs_demos.png``.

With ``--paper-runs`` (the sweep's run dirs) the paper's own recipe goes beside ours: its groups
4, 8 and 9, which differ only in the demo count (60, 20, 10), as the sweep trained and evaluated
them (``OUT/paper_config.json``, a second table and a second line in the figure).
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path
from typing import Any

from mimicrete import tasks
from mimicrete.console import show_messages
from mimicrete.demonstrator import TASKS as DEMONSTRATED
from mimicrete.learn.run_files import atomic_write

from .markdown import steps
from .paper import PAPER_TABLE5
from .sweep_runs import load_runs, missing_dir

DEFAULT_COUNTS = (60, 20, 10, 5)
DEFAULT_SEEDS = (0, 1, 2)
#: synth-hands seed of each demo count (``make demos`` uses 0): fixed, so the demos are the same
HAND_SEEDS = {60: 400, 20: 300, 10: 100, 5: 200}
TARGET = 0.97
#: the paper's groups that differ only in the number of demos (Table 3): group -> demos
PAPER_DEMO_GROUPS = {4: 60, 8: 20, 9: 10}


def hand_seed(count: int) -> int:
    return HAND_SEEDS.get(count, 1000 + count)


def make_demos(task: str, count: int, out: Path) -> Path:
    """``count`` demos of ``task`` in ``out/demos/<task>-<count>`` (made once)."""
    from mimicrete.learn.demo_data import ensure_demos

    d = out / "demos" / f"{task}-{count}"
    hands = out / "hands" / f"{task}-{count}"
    return ensure_demos(d, count, task=task, hand_dir=hands, seed=hand_seed(count), at_least=count)


def checkpoint_evals(run_dir: Path, episodes: int = 100) -> list[dict[str, Any]]:
    """The deterministic evaluation (the run's eval seed) of every checkpoint, with the training's
    elapsed seconds at its step; written to ``checkpoint_evals.json``."""
    import torch

    from mimicrete.learn.evaluate import run_episodes
    from mimicrete.learn.run_files import load_checkpoint, load_policy

    actor, cfg = load_policy(run_dir)
    with open(run_dir / "scalars.csv") as f:
        elapsed = {
            int(float(r["step"])): float(r.get("Environment/Elapsed Seconds") or "nan")
            for r in csv.DictReader(f)
        }
    out = []
    for ck in sorted((run_dir / "checkpoints").glob("step_*.pt")):
        state = load_checkpoint(ck)
        actor.load_state_dict(state["actor"])
        with torch.no_grad():
            res = run_episodes(
                actor, cfg.env_settings.env_id, episodes, cfg.env_settings.seed + 10_000
            )
        step = int(state["step"])
        out.append({"step": step, "elapsed_s": elapsed.get(step, float("nan")), **res})
    atomic_write(run_dir / "checkpoint_evals.json", json.dumps(out, indent=1))
    return out


def run_one(
    task: str, count: int, seed: int, args: argparse.Namespace, demos: Path
) -> dict[str, Any]:
    """Train (unless already done) and evaluate one (demo count, seed); its summary row."""
    from mimicrete import learn
    from mimicrete.learn import config
    from mimicrete.learn.evaluate import evaluate_run

    run_dir = Path(args.out) / f"{task}-d{count}-s{seed}"
    summary = run_dir / "demos_needed.json"
    if summary.exists():
        return json.loads(summary.read_text())
    t = tasks.get(task)
    cfg, _ = config.resolve(
        args.config,
        overrides=[f"env_settings.env_id={t.env_id}", *args.set],
        seed=seed,
        max_steps=args.max_steps,
    )
    # every checkpoint is kept: the first one that evaluates >= 97 % is looked up among them
    every = max(1, cfg.behavior.checkpoint_interval)
    cfg.behavior.keep_checkpoints = max(
        cfg.behavior.keep_checkpoints, -(-cfg.behavior.max_steps // every) + 1
    )
    t0 = time.perf_counter()
    learn.train(cfg, run_dir, demos=str(demos), force=True, progress=not args.no_progress)
    train_s = time.perf_counter() - t0
    det = evaluate_run(run_dir, args.episodes)
    sto = evaluate_run(run_dir, args.episodes, stochastic=True)
    rob = evaluate_run(run_dir, args.episodes, robust=True) if task != "screw" else None
    cks = checkpoint_evals(run_dir, args.episodes)
    first = next((c for c in cks if c["installed_rate"] >= TARGET), None)
    row = {
        "task": task,
        "demos": count,
        "seed": seed,
        "max_steps": cfg.behavior.max_steps,
        "success": t.success,
        "installed": det["installed_rate"],
        "picked": det["picked_rate"],
        "mean_length": det["mean_episode_length"],
        "installed_stochastic": sto["installed_rate"],
        "installed_robust": None if rob is None else rob["installed_rate"],
        "first_97_step": None if first is None else first["step"],
        "first_97_elapsed_s": None if first is None else first["elapsed_s"],
        "train_wall_clock_s": train_s,
    }
    atomic_write(summary, json.dumps(row, indent=1))
    return row


def _secs(x: float) -> str:
    return f"{x:.0f} s"


def _pct(x: float | None) -> str:
    return "–" if x is None else f"{x:.0%}"


def table(rows: list[dict[str, Any]]) -> str:
    """The Markdown table of the rows, one line per (task, demo count)."""
    head = (
        "| task | demos | steps | success per seed | picked | sampled | robust starts | "
        "first ≥ 97 % (steps, training s) | training wall clock |\n"
        "|---|---|---|---|---|---|---|---|---|\n"
    )
    groups: dict[tuple[str, int], list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault((r["task"], r["demos"]), []).append(r)
    lines = []
    for (task, n), rs in groups.items():
        rs.sort(key=lambda r: r["seed"])
        first = [
            "never" if r["first_97_step"] is None
            else f"{steps(r['first_97_step'])}, {r['first_97_elapsed_s']:.0f} s"
            for r in rs
        ]  # fmt: skip
        lines.append(
            f"| {task} | {n} | {steps(rs[0]['max_steps'])} | "
            f"{' / '.join(_pct(r['installed']) for r in rs)} | "
            f"{' / '.join(_pct(r['picked']) for r in rs)} | "
            f"{' / '.join(_pct(r['installed_stochastic']) for r in rs)} | "
            f"{' / '.join(_pct(r['installed_robust']) for r in rs)} | "
            f"{' / '.join(first)} | "
            f"{' / '.join(_secs(r['train_wall_clock_s']) for r in rs)} |"
        )
    return head + "\n".join(lines) + "\n"


def _last(curve: tuple[Any, Any] | None) -> float | None:
    return float(curve[1][-1]) if curve is not None and len(curve[1]) else None


def _mins(x: float | None) -> str:
    return "–" if x is None else f"{x / 60:.0f} min"


def paper_config_rows(roots: list[Path]) -> list[dict[str, Any]]:
    """The evaluated runs of groups 4, 8 and 9 under the sweep's run dirs, one row each."""
    rows = []
    for r in load_runs([Path(p) for p in roots]):
        if r.group in PAPER_DEMO_GROUPS and r.eval is not None:
            rows.append({
                "group": r.group,
                "demos": PAPER_DEMO_GROUPS[r.group],
                "seed": r.seed,
                "max_steps": r.max_steps,
                "installed": r.eval["installed_rate"],
                "installed_stochastic": (r.eval_sampled or {}).get("installed_rate"),
                "trained_steps": r.final_step,
                "converged_at": r.converged_at,
                "train_wall_clock_s": _last(r.scalars.get("Environment/Elapsed Seconds")),
            })  # fmt: skip
    return rows


def paper_table(rows: list[dict[str, Any]]) -> str:
    """The Markdown table of the paper's config here, one line per group, beside the paper's."""
    head = (
        "| paper's config | demos | budget | installed per seed | sampled | trained steps "
        "(c: stopped on convergence) | training wall clock | paper installed |\n"
        "|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for g in sorted({r["group"] for r in rows}, key=lambda g: PAPER_DEMO_GROUPS[g]):
        rs = sorted((r for r in rows if r["group"] == g), key=lambda r: r["seed"])
        trained = [steps(r["trained_steps"]) + (" c" if r["converged_at"] else "") for r in rs]
        lines.append(
            f"| group {g} | {PAPER_DEMO_GROUPS[g]} | {steps(rs[0]['max_steps'])} | "
            f"{' / '.join(_pct(r['installed']) for r in rs)} | "
            f"{' / '.join(_pct(r['installed_stochastic']) for r in rs)} | "
            f"{' / '.join(trained)} | {' / '.join(_mins(r['train_wall_clock_s']) for r in rs)} | "
            f"{_pct(PAPER_TABLE5[g][1])} |"
        )
    return head + "\n".join(lines) + "\n"


def figure(
    rows: list[dict[str, Any]], path: Path, paper_rows: list[dict[str, Any]] | None = None
) -> Path:
    """Success rate (deterministic, 100 episodes) against the demo count: every seed a dot, the
    mean a line, per task; the paper's group 4 / 8 / 9 results beside ours for TileSuction, and
    the paper's config as trained here (``paper_rows``) when given."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 3.6), dpi=120)
    for task in sorted({r["task"] for r in rows}):
        rs = [r for r in rows if r["task"] == task]
        counts = sorted({r["demos"] for r in rs})
        means = [sum(r["installed"] for r in rs if r["demos"] == n) /
                 sum(1 for r in rs if r["demos"] == n) for n in counts]  # fmt: skip
        line = ax.plot(counts, [100 * m for m in means], marker="o", label=f"ours ({task})")[0]
        ax.scatter([r["demos"] for r in rs], [100 * r["installed"] for r in rs],
                   color=line.get_color(), alpha=0.35, s=18)  # fmt: skip
    if paper_rows:
        counts = sorted({r["demos"] for r in paper_rows})
        means = [100 * sum(r["installed"] for r in paper_rows if r["demos"] == n) /
                 sum(1 for r in paper_rows if r["demos"] == n) for n in counts]  # fmt: skip
        ax.plot(counts, means, "^-", color="k", label="paper's config here (groups 9, 8, 4)")
        ax.scatter([r["demos"] for r in paper_rows], [100 * r["installed"] for r in paper_rows],
                   color="k", marker="^", alpha=0.3, s=18)  # fmt: skip
    paper = [100 * PAPER_TABLE5[g][1] for g in sorted(PAPER_DEMO_GROUPS, key=PAPER_DEMO_GROUPS.get)]
    ax.plot(sorted(PAPER_DEMO_GROUPS.values()), paper, "s--", color="grey",
            label="paper (groups 9, 8, 4)")  # fmt: skip
    ax.set_xscale("log")
    ax.minorticks_off()
    ax.set_xticks([5, 10, 20, 60], ["5", "10", "20", "60"])
    ax.set_xlabel("demonstrations")
    ax.set_ylabel("success, % of 100 episodes")
    ax.set_ylim(-5, 105)
    ax.axhline(97, color="k", lw=0.6, ls=":")
    ax.legend(fontsize=8, loc="lower right")
    ax.set_title("Success against the number of demonstrations", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m mimicrete.experiments.demos_needed",
        description="Our learner (configs/fewdemo.yaml) against the number of demonstrations: "
        "make demos, train every (count, seed), evaluate, table and figure.",
    )
    # the demos are the scripted demonstrator's: the tasks it demonstrates (not the row yet)
    p.add_argument("--task", choices=list(DEMONSTRATED), default="suction", help="task (suction)")
    p.add_argument("--counts", type=int, nargs="+", default=list(DEFAULT_COUNTS),
                   help="demo counts (60 20 10 5)")  # fmt: skip
    p.add_argument("--seeds", type=int, nargs="+", default=list(DEFAULT_SEEDS),
                   help="training seeds (0 1 2)")  # fmt: skip
    p.add_argument("--config", default="configs/fewdemo.yaml", help="learner config")
    p.add_argument("--max-steps", type=int, default=300_000, help="env steps per run (300000)")
    p.add_argument("--episodes", type=int, default=100, help="evaluation episodes (100)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="config override for every run (repeatable)")  # fmt: skip
    p.add_argument("--out", default="runs/demos_needed", help="output dir (runs/demos_needed)")
    p.add_argument("--paper-runs", nargs="+", metavar="DIR",
                   help="the sweep's run dirs: put the paper's groups 4, 8 and 9 beside ours "
                   "(kept in OUT/paper_config.json for later calls)")  # fmt: skip
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    return p


def main(argv: list[str] | None = None) -> int:
    """Exit 0; 2 with one line on bad input (arguments, config, demos, run dir); 130 on Ctrl-C
    (finished runs and their files stay whole: every file is written atomically, and a run
    interrupted mid-training is trained again from the start next time)."""
    args = build_parser().parse_args(argv)
    show_messages()
    from mimicrete import learn
    from mimicrete.learn import config

    def error(msg: str) -> int:
        print(f"demos_needed: error: {msg}", file=sys.stderr)
        return 2

    if any(n < 1 for n in args.counts) or args.max_steps < 1 or args.episodes < 1:
        return error("counts, --max-steps and --episodes must be positive")
    bad = missing_dir("--paper-runs", args.paper_runs or [])
    if bad:
        return error(bad)
    try:  # the config is checked before any demo is made
        config.resolve(args.config, overrides=[f"env_settings.env_id={tasks.get(args.task).env_id}",
                                               *args.set])  # fmt: skip
        return _run(args)
    except (learn.ConfigError, learn.DemoDataError, learn.RunDirError, FileNotFoundError) as e:
        return error(str(e))
    except KeyboardInterrupt:
        print("demos_needed: interrupted; finished runs are kept", file=sys.stderr)
        return 130


def _run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in args.counts:
        demos = make_demos(args.task, n, out)
        for seed in args.seeds:
            row = run_one(args.task, n, seed, args, demos)
            print(
                f"{args.task} {n} demos seed {seed}: {row['success']} {_pct(row['installed'])} "
                f"(sampled {_pct(row['installed_stochastic'])}, robust "
                f"{_pct(row['installed_robust'])}), first >= 97 %: {row['first_97_step']}",
                flush=True,
            )
            rows.append(row)
    prev = out / "summary.json"
    done = {(r["task"], r["demos"], r["seed"]) for r in rows}
    old = json.loads(prev.read_text()) if prev.exists() else []
    keep = [r for r in old if (r["task"], r["demos"], r["seed"]) not in done]
    rows = sorted(keep + rows, key=lambda r: (r["task"], -r["demos"], r["seed"]))
    atomic_write(prev, json.dumps(rows, indent=1))
    paper_file = out / "paper_config.json"
    paper_rows = None
    if args.paper_runs:
        paper_rows = paper_config_rows([Path(p) for p in args.paper_runs])
        atomic_write(paper_file, json.dumps(paper_rows, indent=1))
    elif paper_file.exists():
        paper_rows = json.loads(paper_file.read_text())
    md = table(rows) + ("\n" + paper_table(paper_rows) if paper_rows else "")
    atomic_write(out / "summary.md", md)
    print(md)
    fig = figure(rows, out / "installed_vs_demos.png", paper_rows)
    print(f"wrote {prev}, {out / 'summary.md'}, {fig}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
