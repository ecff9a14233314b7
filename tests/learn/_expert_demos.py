"""Demonstrations of the Rust scripted expert (``_native.SimExpert``) for the trainer tests on the
real env: episodes run through ``gymnasium.make("mimicrete/<Task>-v0")``, as the arrays of
``mimicrete.demos.load`` (obs, actions, rewards, terminated, truncated, episode), which a test
saves as an ``.npz`` demo (the trainer reads one directly). Quicker than the hand-derived MCAP
demos (``synth-hands`` + ``convert``), which the tests of that path use."""

from __future__ import annotations

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
