"""`python train.py [FLAGS]` is `mimicrete train --make-demos --stop-on-convergence [FLAGS]`.

With no flags it trains the paper's best configuration measured here (configs/group3.yaml) for
up to 1M steps on the demos in demos/suction, stopping early once training has converged
(installed >= 99 % in 3 summaries in a row; run.json records it), evaluates it on 100 episodes
and writes plots, all in runs/group3-seed0/. On a fresh checkout there are no demos yet: it
makes them first (a scripted person's hand logs in data/hands/suction, turned into MCAP demos by
the teleoperation path, exactly as `make demos`) and says so."""

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

if __name__ == "__main__":
    sys.exit(main(["train", "--make-demos", "--stop-on-convergence", *sys.argv[1:]], program=True))
