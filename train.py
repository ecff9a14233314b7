"""`python train.py [FLAGS]` is `mimicrete train --make-demos [FLAGS]`: with no flags it trains the
paper's best configuration measured here (configs/group3.yaml) for 1M steps on the demos in
demos/suction, evaluates it on 100 episodes and writes plots, all in runs/group3-seed0/. On a
fresh checkout there are no demos yet: it makes them first (a scripted person's hand logs in
data/hands/suction, turned into MCAP demos by the teleoperation path, exactly as `make demos`)
and says so."""

import sys

from mimicrete.cli import main

if __name__ == "__main__":
    sys.exit(main(["train", "--make-demos", *sys.argv[1:]]))
