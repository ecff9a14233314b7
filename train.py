"""`python train.py [FLAGS]` is `mimicrete train --make-demos --stop-on-convergence --config
configs/wide_gen5.yaml --compare tests/learn/data/group3_policy.pt [FLAGS]` (a --config or --compare
among FLAGS replaces the default; the comparison is left out where that file is missing).

With no flags it trains what does best on the wide starts (docs/wide_starts.md),
configs/wide_gen5.yaml: 5 of the demos in demos/suction turned into 500 demos at the wide starts
(demos/gen5, made by `mimicrete demogen` when missing), trained for up to 1M steps, stopping early
once training has converged (installed >= 99 % in 3 summaries in a row; run.json records it). It
evaluates the policy on 100 episodes from the paper's training starts and 100 from the wide starts,
beside the paper's recipe (group 3, trained on the 60 demos) on the same starts and the paper's own
Table 5 row, and draws both policies' success over the table (success_map.png), all in
runs/wide_gen5-seed0/. On a fresh checkout there are no demos yet: it makes them first (a scripted
person's hand logs in data/hands/suction, turned into MCAP demos by the teleoperation path, exactly
as `make demos`, then the generated ones) and says so."""

import os
import signal
import sys


def _interrupted(signum, frame):  # Ctrl-C while the imports run: quiet, exit 130
    try:
        os.write(2, b"mimicrete train: interrupted\n")
    finally:
        os._exit(130)


if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, _interrupted)  # mimicrete.cli.main takes over once it runs

from mimicrete.cli import main  # noqa: E402


def _defaults(flags: list[str]) -> list[str]:
    given = {f.split("=", 1)[0] for f in flags}
    out = [] if "--config" in given else ["--config", "configs/wide_gen5.yaml"]
    paper = os.path.join(os.path.dirname(os.path.abspath(__file__)), "tests", "learn", "data",
                         "group3_policy.pt")  # fmt: skip
    if "--compare" not in given and os.path.isfile(paper):
        out += ["--compare", paper]
    return out


if __name__ == "__main__":
    flags = sys.argv[1:]
    cmd = ["train", "--make-demos", "--stop-on-convergence", *_defaults(flags), *flags]
    sys.exit(main(cmd, program=True))
