"""`mimicrete eval RUN_DIR --episodes 100`: the paper's Table 5 row for a trained run, written to
``RUN_DIR/eval.json``. Parses the flags and calls ``mimicrete.learn.evaluate_run``."""

from __future__ import annotations

import argparse
from pathlib import Path

from mimicrete.cli import UsageError


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", help="a run directory written by `mimicrete train`")
    parser.add_argument("--episodes", type=int, default=100, help="episodes to run (100)")
    parser.add_argument("--seed", type=int, help="eval env seed (default: run seed + 10000)")


def main(args: argparse.Namespace) -> int:
    run_dir = Path(args.run_dir)
    if args.episodes < 1:
        raise UsageError(f"--episodes: at least 1, got {args.episodes}")
    if args.seed is not None and args.seed < 0:
        raise UsageError(f"--seed: 0 or more, got {args.seed}")
    if not run_dir.is_dir():
        raise UsageError(f"{run_dir}: no such run directory")
    import torch

    from mimicrete import learn
    from mimicrete.learn.run_files import PolicyFileError

    torch.set_num_threads(1)
    try:
        res = learn.evaluate_run(run_dir, args.episodes, args.seed)
    except PolicyFileError as e:
        raise UsageError(str(e)) from None
    print(learn.format_row(run_dir.name, res))
    print(f"wrote {run_dir / 'eval.json'}")
    return 0
