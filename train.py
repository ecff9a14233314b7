"""`python train.py [FLAGS]` is `mimicrete train --make-demos --stop-on-convergence --config
configs/place_gen5.yaml [FLAGS]` (a --config among FLAGS replaces the default).

With no flags it trains the main job: TilePlace, the tile set down square on its pad as a tiler
means it (crates/tile-sim/tasks/tile_place.toml: the cups hold only sealed on the face, the held
tile still collides, success = placed within 5 mm and 2 degrees). configs/place_gen5.yaml: 5 of
the demos in demos/place turned into 500 demos at the wide starts, played 4 times faster
(demos/gen_place5_x4, made by `mimicrete demogen` when missing); BC pretraining, then PPO + BC
with a reverse curriculum, for up to 2M steps, stopping early once training has converged (placed
>= 99 % in 3 summaries in a row; run.json records it). It evaluates the policy on 100 episodes
from the paper's training starts and 100 from the wide starts, prints where the tiles ended (the
placement tables) and draws its success over the table (success_map.png), all in
runs/place_gen5-seed0/. On a fresh checkout there are no demos yet: it makes them first (a
scripted person's hand logs in data/hands/place, turned into MCAP demos by the teleoperation path,
exactly as `make demos-place`, then the generated ones) and says so.

The paper's task and rule (TileSuction, installed = the tile's centre within 3 cm, still held) keep
their own config: `python train.py --config configs/wide_gen5.yaml --compare
tests/learn/data/group3_policy.pt` is what this script ran before (docs/RESULTS.md)."""

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
    return [] if "--config" in given else ["--config", "configs/place_gen5.yaml"]


if __name__ == "__main__":
    flags = sys.argv[1:]
    cmd = ["train", "--make-demos", "--stop-on-convergence", *_defaults(flags), *flags]
    sys.exit(main(cmd, program=True))
