"""Trainer benchmark: env steps per second of our PPO (rollout + update, the paper's 256 x 3 nets,
buffer 10240, batch 512, 3 epochs) against Stable-Baselines3's PPO with the same sizes on the same
env, in the same process; plus the cost of GAIL and BC on top, and the real env if it is built.

``python -m mimicrete.bench train`` (part of ``make bench``). Prints, asserts nothing.
"""

from __future__ import annotations

import contextlib
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

BUFFER = 10240
NUM_ENVS = 32
UPDATES = 2


def _our_steps_per_s(cfg, tmp: Path, demos: str | None = None) -> tuple[float, float, float]:
    """(total steps/s, rollout-only steps/s, seconds per update) over UPDATES updates."""
    from mimicrete.learn import update
    from mimicrete.learn.trainer import Trainer

    tr = Trainer(cfg, tmp / "run", demos, 5_000_000)
    spent: dict[str, float] = {"rollout": 0.0}
    t0 = time.perf_counter()
    with _timed(spent, (update, "collect_rollout", "rollout")):
        for _ in range(UPDATES):
            tr.iterate()
    t_roll = spent["rollout"]
    t_upd = time.perf_counter() - t0 - t_roll
    steps = UPDATES * BUFFER
    return steps / (t_roll + t_upd), steps / t_roll, t_upd / UPDATES


@contextlib.contextmanager
def _timed(spent: dict[str, float], *targets: tuple[object, str, str]):
    """While inside: every call of ``obj.name`` adds its time to ``spent[label]``, for each
    ``(obj, name, label)``. The update's steps are functions of ``learn.update`` that
    ``one_update`` calls by name, so timing them there times them in ``Trainer.iterate``."""
    saved = []
    for obj, name, label in targets:
        f = getattr(obj, name)
        saved.append((obj, name, f))

        def g(*a, _f=f, _label=label, **k):
            t = time.perf_counter()
            try:
                return _f(*a, **k)
            finally:
                spent[_label] = spent.get(_label, 0.0) + time.perf_counter() - t

        setattr(obj, name, g)
    try:
        yield
    finally:
        for obj, name, f in saved:
            setattr(obj, name, f)


def _update_breakdown(cfg, tmp: Path) -> None:
    """Where an update's time goes (BC + GAIL + PPO), per part, and the GAE critic pass before
    (two passes of T x N rows: every observation and every true next one) and after (one pass
    over the distinct observations), timed on the same rollouts."""
    from mimicrete.learn import update
    from mimicrete.learn.trainer import Trainer

    tr = Trainer(cfg, tmp / "breakdown", None, 5_000_000)
    spent: dict[str, float] = {}
    parts = (
        (update, "collect_rollout", "rollout"),
        (update, "ppo_step", "PPO minibatch steps"),
        (update, "discriminator_steps", "GAIL discriminator steps"),
        (tr.state.gail, "rewards", "GAIL rewards on the rollout"),
        (update, "bc_update", "BC round"),
        (update, "advantages", "GAE (critic pass + GAE)"),
    )
    whole = "whole update (rollout, signals, GAIL, GAE, PPO, BC)"
    gae_old = gae_new = 0.0
    for _ in range(UPDATES):
        t = time.perf_counter()
        with _timed(spent, *parts):
            tr.iterate()
        spent[whole] = spent.get(whole, 0.0) + time.perf_counter() - t
        ro = tr.state.rollout  # the update's rollout, for the two ways of the GAE critic pass
        T, N, D = ro.T, ro.N, tr.obs_dim
        with torch.no_grad():
            t0 = time.perf_counter()
            tr.state.critic(torch.from_numpy(ro.obs.reshape(T * N, D)))
            tr.state.critic(torch.from_numpy(ro.next_obs().reshape(T * N, D)))
            t1 = time.perf_counter()
            ro.values_and_next(lambda x: tr.state.critic(torch.from_numpy(x)).numpy())
            t2 = time.perf_counter()
        gae_old += t1 - t0
        gae_new += t2 - t1
    tr.close()
    print(f"  where a BC+GAIL+PPO update goes (toy env, mean of {UPDATES} updates):")
    for label, sec in spent.items():
        print(f"    {label:<46s} {sec / UPDATES:6.2f} s")
    print(
        f"    GAE critic pass: two full passes {gae_old / UPDATES:.3f} s, distinct observations "
        f"only {gae_new / UPDATES:.3f} s ({gae_old / max(gae_new, 1e-9):.2f}x)"
    )


def _toy_cfg(tmp: Path, gail: float, bc: float, overlap_gail: bool = False):
    from mimicrete.learn import config
    from mimicrete.testing.toyenv import toy_config

    c = toy_config(tmp, buffer=BUFFER, batch=512, num_envs=NUM_ENVS, gail=gail, bc=bc)
    return config.with_overrides(
        c,
        [
            f"torch_settings.overlap_gail={str(overlap_gail).lower()}",
            "behavior.network_settings.hidden_units=256",
            "behavior.network_settings.num_layers=3",
            "behavior.hyperparameters.num_epoch=3",
            "behavior.reward_signals.gail.network_settings.hidden_units=256"
            if gail
            else "behavior.time_horizon=400",
            "behavior.reward_signals.gail.network_settings.num_layers=3"
            if gail
            else "behavior.time_horizon=400",
            "behavior.max_steps=5000000",
            "behavior.checkpoint_interval=100000000",
        ],
    )


def _sb3_steps_per_s() -> float | None:
    try:
        import gymnasium as gym
        from stable_baselines3 import PPO
        from stable_baselines3.common.vec_env import DummyVecEnv
    except ImportError:
        return None
    from mimicrete.testing import toyenv

    class One(gym.Env):
        """One toy env as a plain gymnasium Env (SB3 vectorises it itself)."""

        def __init__(self, seed):
            self.v = toyenv.ToyTileVecEnv(1, seed=seed)
            self.observation_space = self.v.single_observation_space
            self.action_space = self.v.single_action_space

        def reset(self, *, seed=None, options=None):
            o, _ = self.v.reset(seed=seed)
            return o[0], {}

        def step(self, a):
            o, r, te, tr, info = self.v.step(np.asarray(a, np.float32)[None])
            obs = info["final_obs"][0] if (te[0] or tr[0]) else o[0]
            return obs, float(r[0]), bool(te[0]), bool(tr[0]), {}

    venv = DummyVecEnv([lambda i=i: One(i) for i in range(NUM_ENVS)])
    model = PPO(
        "MlpPolicy",
        venv,
        n_steps=BUFFER // NUM_ENVS,
        batch_size=512,
        n_epochs=3,
        learning_rate=5e-4,
        ent_coef=0.01,
        gae_lambda=0.95,
        policy_kwargs={"net_arch": [256, 256, 256]},
        device="cpu",
        seed=0,
        verbose=0,
    )
    t0 = time.perf_counter()
    model.learn(total_timesteps=UPDATES * BUFFER)
    return UPDATES * BUFFER / (time.perf_counter() - t0)


def run() -> None:
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        print(
            f"PPO, 256x3 nets, buffer {BUFFER}, batch 512, 3 epochs, {NUM_ENVS} envs, "
            f"{UPDATES} updates, torch threads 1"
        )
        ours, roll, upd = _our_steps_per_s(_toy_cfg(tmp, 0.0, 0.0), tmp)
        print(
            f"  toy env, ours (PPO only):     {ours:8.0f} steps/s  (rollout {roll:.0f} steps/s, "
            f"update {upd:.2f} s)"
        )
        sb3 = _sb3_steps_per_s()
        if sb3 is not None:
            torch.set_num_threads(1)
            print(
                f"  toy env, SB3 PPO (peer):      {sb3:8.0f} steps/s  -> ours / SB3 = "
                f"{ours / sb3:.2f}x"
            )
        full, roll, upd = _our_steps_per_s(_toy_cfg(tmp, 0.01, 0.5), tmp)
        print(
            f"  toy env, ours (BC+GAIL+PPO):  {full:8.0f} steps/s  (rollout {roll:.0f} steps/s, "
            f"update {upd:.2f} s; GAIL in line: before)"
        )
        over, roll, upd2 = _our_steps_per_s(_toy_cfg(tmp, 0.01, 0.5, overlap_gail=True), tmp)
        print(
            f"  toy env, ours (BC+GAIL+PPO):  {over:8.0f} steps/s  (rollout {roll:.0f} steps/s, "
            f"update {upd2:.2f} s; GAIL on its own thread, overlap_gail: after) -> "
            f"{over / full:.2f}x steps/s, update {upd / upd2:.2f}x"
        )
        _update_breakdown(_toy_cfg(tmp, 0.01, 0.5), tmp)
        try:
            from mimicrete.learn import config
            from mimicrete.learn.env import make_env

            make_env("TileSuction-v0", 2, 0).close()
        except Exception as e:  # the Rust env is not built yet
            print(f"  TileSuction-v0: not available ({type(e).__name__}: {e})")
            return
        cfg = config.load(Path(__file__).resolve().parents[3] / "configs" / "group1.yaml")
        ours, roll, upd = _our_steps_per_s(cfg, tmp)
        print(
            f"  TileSuction-v0, group1 (PPO): {ours:8.0f} steps/s  (rollout {roll:.0f} steps/s, "
            f"update {upd:.2f} s) -> 1M steps in {1e6 / ours / 60:.1f} min"
        )
        root = Path(__file__).resolve().parents[3]
        if not any((root / "demos" / "suction").glob("*.mcap")):
            print("  TileSuction-v0, group3: no demos in demos/suction (make demos)")
            return
        rates = {}
        for overlap in (False, True):
            cfg = config.with_overrides(
                config.load(root / "configs" / "group3.yaml"),
                [
                    f"torch_settings.overlap_gail={str(overlap).lower()}",
                    "behavior.behavioral_cloning.pretrain_steps=0",
                ],
            )
            rates[overlap] = _our_steps_per_s(cfg, tmp, str(root / "demos" / "suction"))
        (a, _, ua), (b, _, ub) = rates[False], rates[True]
        print(
            f"  TileSuction-v0, group3 (BC+GAIL+PPO): GAIL in line {a:.0f} steps/s (update "
            f"{ua:.2f} s), on its own thread {b:.0f} steps/s (update {ub:.2f} s) -> {b / a:.2f}x "
            f"-> 1M steps in {1e6 / b / 60:.1f} min"
        )
