"""What GAIL's survivor-bias handling changes, in a short run you can repeat:
``python -m mimicrete.learn.survivor_demo [--steps 200000] [--env Toy-v0 | TileSuction-v0]``.

Trains the same configuration twice, with ``survivor_bias: none`` (ML-Agents exactly) and
``bootstrap`` (ours), and prints the Table-5 row of each. Default: group 5's strengths (extrinsic
1.0, GAIL 0.1, BC 0.5) on the numpy toy env with 12 toy expert demos, small nets, BC warm start.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from . import config, evaluate
from .loop import train
from .toyenv import toy_config


def run(mode: str, steps: int, gail: float, ext: float, seed: int, tmp: Path) -> dict:
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


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--steps", type=int, default=200_000)
    p.add_argument("--gail", type=float, default=0.1)
    p.add_argument("--extrinsic", type=float, default=1.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", help="keep the runs here (default: a temporary dir)")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(a.out or d)
        tmp.mkdir(parents=True, exist_ok=True)
        for mode in ("none", "bootstrap"):
            r = run(mode, a.steps, a.gail, a.extrinsic, a.seed, tmp)
            print(
                f"survivor_bias={mode:<9} picked {r['picked_rate']:.0%}  installed "
                f"{r['installed_rate']:.0%}  mean length {r['mean_episode_length']:.1f}  "
                f"({r['train_seconds']:.0f} s)  {json.dumps(r)}"
            )


if __name__ == "__main__":
    main()
