"""Interim demonstrations from the Rust scripted expert (``_native.SimExpert``) run through
``gymnasium.make("mimicrete/<Task>-v0")``, saved as ``.npz`` with the arrays of
``mimicrete.demos.load`` (obs, actions, rewards, terminated, truncated, episode). The trainer reads
an ``.npz`` demo path directly. For when the hand-derived MCAP demos are not available:
``python -m mimicrete.learn.scripted_demos --episodes 60 --seed 0 --out demos/expert.npz``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def scripted_demos(
    episodes: int, seed: int = 0, task: str = "TileSuction", successful_only: bool = True
) -> dict[str, np.ndarray]:
    import gymnasium as gym

    from mimicrete import _native, envs
    from mimicrete.demos import STEP_DTYPES, step_arrays

    envs.register_envs()
    env = gym.make(f"mimicrete/{task}-v0")
    sim = env.unwrapped.sim
    expert = _native.SimExpert(task)
    rows: dict[str, list] = {k: [] for k in STEP_DTYPES}
    ep, s = 0, seed
    while ep < episodes:
        obs, _ = env.reset(seed=s)
        s += 1
        expert.reset()
        ep_rows: dict[str, list] = {k: [] for k in rows}
        while True:
            a = np.asarray(expert.act(sim), np.float32)
            nobs, r, term, trunc, info = env.step(a)
            for k, v in (
                ("obs", obs),
                ("actions", a),
                ("rewards", r),
                ("terminated", term),
                ("truncated", trunc),
                ("episode", ep),
            ):
                ep_rows[k].append(v)
            obs = nobs
            if term or trunc:
                break
        if successful_only and not info.get("installed", False):
            continue
        for k in rows:
            rows[k].extend(ep_rows[k])
        ep += 1
    env.close()
    return step_arrays(rows)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--episodes", type=int, default=60)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--task", default="TileSuction")
    p.add_argument("--out", required=True)
    a = p.parse_args()
    d = scripted_demos(a.episodes, a.seed, a.task)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(a.out, **d)
    lens = np.bincount(d["episode"])
    print(
        f"wrote {a.episodes} episodes, {len(d['obs'])} steps (mean length {lens.mean():.1f}) "
        f"to {a.out}"
    )


if __name__ == "__main__":
    main()
