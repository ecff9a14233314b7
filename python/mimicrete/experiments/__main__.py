"""``python -m mimicrete.experiments``: Table 3's groups x seeds as a Ray Tune sweep, then
docs/RESULTS.md (see ``sweep.py`` for what it does, ``report.py`` for the report)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from mimicrete.console import show_messages

from .sweep import (
    DEFAULT_MAX_STEPS,
    DEFAULT_NAME,
    DEFAULT_OUT,
    DEFAULT_SEEDS,
    SWEEP_FILE,
    run_sweep,
)
from .trials import repo_root


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
    p.add_argument(
        "--stop-on-convergence",
        action="store_true",
        help="end a trial once training has converged (installed >= 99 %% in 3 summaries in a "
        "row, as the paper stopped; run.json records the step)",
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
    show_messages()
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
        from .report import write_report

        out = Path(args.report_out)
        write_report(
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
