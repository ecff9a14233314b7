"""`mimicrete demogen`: a few recorded demos → many successful demos at new starts
(:mod:`mimicrete.demogen`, object-centric generation as in MimicGen). The task (TileSuction,
BlockGrip, Screw, TilePlace) is the source demos' own, read from their metadata; ``--task`` only
checks it."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from mimicrete.cli import UsageError


def configure(parser: argparse.ArgumentParser) -> None:
    """Flags of ``mimicrete demogen``."""
    parser.add_argument("--demos", required=True, metavar="DIR", help="source MCAP demos")
    parser.add_argument(
        "--task",
        default=None,
        metavar="suction|grip|screw|place",
        help="the task the source demos must be of (default: theirs, from their metadata)",
    )
    parser.add_argument(
        "--source-count",
        type=int,
        default=None,
        metavar="K",
        help="use the first K installing demos of --demos (default: all)",
    )
    parser.add_argument(
        "--count", required=True, type=int, metavar="N", help="successful demos to write"
    )
    parser.add_argument(
        "--starts",
        default="wide",
        metavar="wide|training|robust|FILE.jsonl",
        help="where the new episodes start: a tile-sim distribution or a starts file "
        "(one JSON object a line, as `mimicrete eval --starts FILE`)",
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="where the demos go")
    parser.add_argument("--seed", type=int, default=0, help="draws of starts and sources")
    parser.add_argument(
        "--max-attempts",
        type=int,
        default=None,
        metavar="M",
        help="give up after M episodes (default 4 x N + 20)",
    )
    parser.add_argument(
        "--action-noise",
        type=float,
        default=None,
        metavar="SIGMA",
        help="standard deviation of Gaussian noise on every played joint action, in units of "
        "the joint step (MimicGen's action noise, 0.05 in its configs); the noisy action is "
        "executed and recorded (default: the task's, 0)",
    )
    parser.add_argument(
        "--grasp-jitter",
        type=float,
        default=0.0,
        metavar="M",
        help="grasp up to M metres off the object's centre, the place corrected for it (default 0)",
    )
    parser.add_argument(
        "--speed",
        type=float,
        default=1.0,
        metavar="X",
        help="play the source demos X times faster (1 to 10; default 1): a person's demo hovers "
        "and creeps where a robot need not; the arm's step limits still apply, and episodes that "
        "then fail are not kept",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="write into an --out that holds demos already"
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def _starts(arg: str, task: str, task_file: str | None = None):  # -> str | list[dict]
    if arg in ("wide", "training", "robust"):
        return arg
    from mimicrete.learn import starts as st

    p = Path(arg)
    if not p.is_file():
        raise UsageError(f"--starts {arg}: neither wide, training, robust nor a file of starts")
    try:
        return list(st.read_starts_file(p, task, task_file).starts)
    except (ValueError, OSError) as e:
        raise UsageError(f"--starts {e}") from None


def main(args: argparse.Namespace) -> int:
    """Run ``mimicrete demogen``; exit 2 for bad input, 1 when fewer than N demos succeeded."""
    from tqdm import tqdm

    from mimicrete import LogFormatError
    from mimicrete import demogen as dg

    if args.count < 1:
        raise UsageError(f"--count must be at least 1, got {args.count}")
    if args.source_count is not None and args.source_count < 1:
        raise UsageError(f"--source-count must be at least 1, got {args.source_count}")
    if args.max_attempts is not None and args.max_attempts < 1:
        raise UsageError(f"--max-attempts must be at least 1, got {args.max_attempts}")
    if args.action_noise is not None and not 0 <= args.action_noise <= 1:
        raise UsageError(f"--action-noise must be in [0, 1], got {args.action_noise}")
    if not 0 <= args.grasp_jitter <= 0.05:
        raise UsageError(f"--grasp-jitter must be in [0, 0.05] m, got {args.grasp_jitter}")
    if not 1 <= args.speed <= 10:
        raise UsageError(f"--speed must be in [1, 10], got {args.speed}")
    if not 0 <= args.seed < 2**32:
        raise UsageError(f"--seed must be in [0, 2**32), got {args.seed}")
    if args.starts not in ("wide", "training", "robust") and not Path(args.starts).is_file():
        raise UsageError(
            f"--starts {args.starts}: neither wide, training, robust nor a file of starts"
        )
    want = None
    if args.task is not None:
        try:
            want = dg.task_frames(args.task).sim
        except dg.DemoGenError as e:
            raise UsageError(f"--task {e}") from None
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: exists and is not a directory")
    if out.is_dir() and any(out.glob("*.mcap")) and not args.overwrite:
        raise UsageError(f"--out {out}: holds demos already (--overwrite to write into it)")
    try:
        sources = dg.load_sources(args.demos, args.source_count)
    except (dg.DemoGenError, LogFormatError) as e:
        raise UsageError(str(e)) from None
    task = sources[0].task
    if want is not None and task != want:
        raise UsageError(f"--task {args.task}: the demos in {args.demos} are {task} demos")
    starts = _starts(args.starts, task, sources[0].task_file)
    bar = tqdm(total=args.count, desc="demogen", unit="demo", disable=args.no_progress)

    def progress(rep: dg.Report) -> None:
        bar.n = rep.kept
        bar.set_postfix(attempts=rep.attempts, yield_=f"{100 * rep.yield_:.0f}%")

    try:
        rep = dg.generate(
            sources,
            args.count,
            out,
            starts=starts,
            seed=args.seed,
            max_attempts=args.max_attempts,
            progress=progress,
            grasp_jitter=args.grasp_jitter,
            action_noise=args.action_noise,
            speed=args.speed,
        )
    except dg.DemoGenError as e:
        raise UsageError(str(e)) from None
    finally:
        bar.close()
    summary = {
        "task": task,
        "sources": [s.name for s in sources],
        "starts": args.starts,
        "seed": args.seed,
        "action_noise": args.action_noise,
        "grasp_jitter": args.grasp_jitter,
        "speed": args.speed,
        "attempts": rep.attempts,
        "kept": rep.kept,
        "yield": round(rep.yield_, 4),
        "seconds": round(rep.seconds, 1),
        "failures": rep.failures,
    }
    (out / "demogen.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(
        f"{rep.kept} {task} demos in {out} from {len(sources)} source demo(s): yield "
        f"{rep.kept}/{rep.attempts} ({100 * rep.yield_:.1f} %) in {rep.seconds:.1f} s"
        + (f"; failures {rep.failures}" if rep.failures else "")
    )
    return 0 if rep.kept >= args.count else 1
