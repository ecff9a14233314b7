"""`python train.py [FLAGS]` is `mimicrete train [FLAGS]`: with no flags it trains the paper's best
configuration measured here (configs/group3.yaml) on the demos in demos/suction, evaluates it and
writes plots.
`make train` makes those demos first (synth-hands + convert)."""

import sys

from mimicrete.cli import main

if __name__ == "__main__":
    sys.exit(main(["train", *sys.argv[1:]]))
