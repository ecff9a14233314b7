"""``python -m mimicrete.experiments.survivor``: GAIL's survivor-bias handling against the
evaluation policy (issue 16), as a Markdown table from run dirs: ML-Agents' ``none`` beside our
``bootstrap`` for the groups whose GAIL strength is 0.1 or more (2, 5, 6, 7), with the paper's row.

The runs are plain ``mimicrete train`` runs (which evaluate the deterministic policy) plus a
sampled evaluation, e.g. group 5 with ``none`` at the paper's 5M steps::

    mimicrete train --config configs/group5.yaml --seed 1 --max-steps 5000000 \\
        --run-dir runs/survivor/group5-none-seed1 \\
        --set behavior.reward_signals.gail.survivor_bias=none
    mimicrete eval --stochastic runs/survivor/group5-none-seed1

Every dir named ``group<g>-...seed<s>`` under the ``--runs`` dirs with both evaluations counts; its
handling and budget come from its own ``resolved_config.yaml`` and ``run.json``, so the sweep's
runs (``bootstrap``) go beside the comparison's without being named again.

``--toy`` repeats the comparison in minutes: the same configuration (group 5's strengths:
extrinsic 1.0, GAIL 0.1, BC 0.5) trained with ``none`` and with ``bootstrap`` on the numpy toy env,
each evaluated on 100 deterministic episodes::

    python -m mimicrete.experiments.survivor --toy [--steps 200000] [--gail 0.1] [--extrinsic 1.0]
"""

from __future__ import annotations

import argparse
import re
import statistics
import sys
from pathlib import Path
from typing import Any

from mimicrete.console import show_messages

from .markdown import steps
from .markdown import table as md_table
from .paper import PAPER_TABLE5
from .sweep_runs import load_run, missing_dir

NAME_RE = re.compile(r"^group(\d+)-(?:.+-)?seed(\d+)$")
DEFAULT_GROUPS = (2, 5, 6, 7)  # GAIL strength 0.1 or more
EVAL_KEYS = ("picked_rate", "installed_rate", "mean_episode_length")


def load(roots: list[Path], groups: tuple[int, ...] = DEFAULT_GROUPS) -> list[dict[str, Any]]:
    """One row per evaluated run dir of ``groups`` under ``roots``: group, seed, handling,
    budget, and the deterministic and sampled (picked, installed, length)."""
    rows = []
    for root in roots:
        for d in sorted(Path(root).iterdir()):
            r = load_run(d, NAME_RE)
            if r is None or r.group not in groups or r.eval is None or r.eval_sampled is None:
                continue
            gail = (r.behavior.get("reward_signals") or {}).get("gail") or {}
            rows.append({
                "group": r.group,
                "seed": r.seed,
                "survivor_bias": gail.get("survivor_bias", "none"),  # the config default
                "max_steps": r.max_steps or r.behavior.get("max_steps"),
                "det": [r.eval[k] for k in EVAL_KEYS],
                "sampled": [r.eval_sampled[k] for k in EVAL_KEYS],
            })  # fmt: skip
    return rows


def _mean_sd(xs: list[float], scale: float, unit: str) -> str:
    if len(xs) == 1:
        return f"{scale * xs[0]:.0f}{unit}"
    return f"{scale * statistics.mean(xs):.0f} ± {scale * statistics.stdev(xs):.0f}{unit}"


def _seeds(xs: list[float]) -> str:
    return " / ".join(f"{100 * x:.0f}" for x in xs) + " %"


def table(rows: list[dict[str, Any]]) -> str:
    """Per (group, handling, budget): the seeds' deterministic rates, the sampled mean ± sd
    (per seed in brackets), and the paper's picked / installed / length."""
    keys = sorted({(r["group"], r["survivor_bias"], r["max_steps"]) for r in rows})
    out = []
    for g, bias, budget in keys:
        rs = sorted((r for r in rows if (r["group"], r["survivor_bias"], r["max_steps"]) ==
                     (g, bias, budget)), key=lambda r: r["seed"])  # fmt: skip
        det, sam = [r["det"] for r in rs], [r["sampled"] for r in rs]
        pp, pi, pl = PAPER_TABLE5[g]
        out.append([
            g, f"`{bias}`", steps(budget), len(rs),
            _seeds([x[0] for x in det]), _seeds([x[1] for x in det]),
            f"{_mean_sd([x[0] for x in sam], 100, ' %')} ({_seeds([x[0] for x in sam])})",
            f"{_mean_sd([x[1] for x in sam], 100, ' %')} ({_seeds([x[1] for x in sam])})",
            _mean_sd([x[2] for x in sam], 1, ""),
            f"{100 * pp:.0f} % / {100 * pi:.0f} % / {pl:.0f}",
        ])  # fmt: skip
    cols = ["group", "survivor bias", "steps", "n", "det. picked", "det. installed",
            "sampled picked", "sampled installed", "sampled length",
            "paper: picked / installed / length"]  # fmt: skip
    return "\n".join(md_table(cols, out)) + "\n"


def toy_run(mode: str, steps: int, gail: float, ext: float, seed: int, tmp: Path) -> dict:
    """One short run on the numpy toy env (``mimicrete.testing.toyenv``: 12 toy expert demos,
    small nets, BC warm start) with ``survivor_bias: mode``, evaluated on 100 deterministic
    episodes; the evaluation's row plus ``train_seconds``."""
    import time

    from mimicrete.learn import config, evaluate
    from mimicrete.learn.loop import train
    from mimicrete.testing.toyenv import toy_config

    c = toy_config(
        tmp,
        max_steps=steps,
        buffer=4096,
        batch=256,
        num_envs=32,
        ckpt=10**9,
        gail=gail,
        bc=0.5,
        survivor_bias=mode,
        seed=seed,
    )
    c = config.with_overrides(
        c,
        [
            f"behavior.reward_signals.extrinsic.strength={ext}",
            "behavior.behavioral_cloning.steps=40000",
            "behavior.behavioral_cloning.pretrain_steps=1500",
            "behavior.hyperparameters.num_epoch=3",
            "behavior.summary_freq=16384",
        ],
    )
    rd = tmp / f"{mode}-gail{gail}-ext{ext}-seed{seed}"
    t0 = time.perf_counter()
    train(c, rd, progress=False)
    res = evaluate.evaluate_run(rd, 100)
    res["train_seconds"] = time.perf_counter() - t0
    return res


def _toy(args: argparse.Namespace) -> int:
    """``--toy``: one configuration trained twice, ``none`` then ``bootstrap``; a line each."""
    import json
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        tmp = Path(args.toy_dir or d)
        tmp.mkdir(parents=True, exist_ok=True)
        for mode in ("none", "bootstrap"):
            r = toy_run(mode, args.steps, args.gail, args.extrinsic, args.seed, tmp)
            print(
                f"survivor_bias={mode:<9} picked {r['picked_rate']:.0%}  installed "
                f"{r['installed_rate']:.0%}  mean length {r['mean_episode_length']:.1f}  "
                f"({r['train_seconds']:.0f} s)  {json.dumps(r)}"
            )
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m mimicrete.experiments.survivor",
        description="GAIL's survivor-bias handling (none / bootstrap) against the evaluation "
        "policy: a Markdown table of the evaluated runs of groups 2, 5, 6 and 7 under the given "
        "dirs (--runs), or a short rerun of both settings on the numpy toy env (--toy).",
    )
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--runs", nargs="+", metavar="DIR",
                       help="dirs holding group<g>-...seed<s> run dirs (e.g. runs/survivor and "
                       "the sweep's runs/table5/runs)")  # fmt: skip
    which.add_argument("--toy", action="store_true",
                       help="train group 5's strengths (by default) twice on the toy env, none "
                       "then bootstrap, and print each evaluation")  # fmt: skip
    p.add_argument("--out", help="also write the table to this file")
    toy = p.add_argument_group("--toy")
    toy.add_argument("--steps", type=int, default=200_000)
    toy.add_argument("--gail", type=float, default=0.1, help="GAIL strength")
    toy.add_argument("--extrinsic", type=float, default=1.0, help="extrinsic strength")
    toy.add_argument("--seed", type=int, default=0)
    toy.add_argument("--toy-dir", help="keep the toy runs here (default: a temporary dir)")
    args = p.parse_args(argv)
    show_messages()
    if args.toy:
        return _toy(args)
    bad = missing_dir("--runs", args.runs)
    if bad:
        print(f"survivor: error: {bad}", file=sys.stderr)
        return 2
    md = table(load([Path(d) for d in args.runs]))
    print(md, end="")
    if args.out:
        from mimicrete.learn.run_files import atomic_write

        atomic_write(Path(args.out), md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
