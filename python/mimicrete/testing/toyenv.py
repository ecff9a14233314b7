"""A tiny, fast, pure-numpy stand-in for the tile task with the same interface as
``mimicrete.envs.make_vec`` (80-dim observation of 5 stacked 16-dim frames, Box(-1, 1, (7,))
action with the end-effector command in the last dimension, the same sparse rewards, SAME_STEP
autoreset with ``final_obs``). Used by the trainer's tests and smoke runs; not a physics model.

A point "end effector" moves by ``STEP * a[0:3]`` per step (a[3:6] are ignored). Suction
(a[6] >= 0.5) within ``PICK_DIST`` of the tile picks it (+1, once); the tile then moves with the
end effector; tile within ``INSTALL_DIST`` of the target installs it (+1, terminated). Drop
(a[6] <= -0.5) while holding makes the tile fall (-0.5, terminated). Tile x is random in [0, 0.15].
Episodes are truncated after ``max_episode_steps``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from mimicrete.demos import STEP_DTYPES, step_arrays

FRAME = 16
STACK = 5
OBS_DIM = FRAME * STACK
ACT_DIM = 7
STEP = 0.03
PICK_DIST = 0.04
INSTALL_DIST = 0.03
EE_START = np.array([0.0, 0.0, 0.3])
TARGET = np.array([0.3, 0.1, 0.3])


class ToyTileVecEnv(VectorEnv):
    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, num_envs: int, max_episode_steps: int = 100, seed: int | None = None):
        self.num_envs = num_envs
        self.max_episode_steps = max_episode_steps
        self.single_observation_space = spaces.Box(-np.inf, np.inf, (OBS_DIM,), np.float32)
        self.single_action_space = spaces.Box(-1.0, 1.0, (ACT_DIM,), np.float32)
        self.observation_space = spaces.Box(-np.inf, np.inf, (num_envs, OBS_DIM), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (num_envs, ACT_DIM), np.float32)
        self._rng = np.random.default_rng(seed)
        self.ee = np.zeros((num_envs, 3))
        self.tile = np.zeros((num_envs, 3))
        self.holding = np.zeros(num_envs, bool)
        self.picked = np.zeros(num_envs, bool)
        self.t = np.zeros(num_envs, np.int64)
        self.frames = np.zeros((num_envs, STACK, FRAME), np.float32)

    def _frame(self, idx: np.ndarray) -> np.ndarray:
        n = len(idx)
        f = np.zeros((n, FRAME), np.float32)
        f[:, 0:3] = self.ee[idx]
        f[:, 6] = self.holding[idx]
        f[:, 7:10] = self.ee[idx]
        f[:, 10:13] = TARGET
        f[:, 13:16] = self.tile[idx]
        return f

    def _reset_idx(self, idx: np.ndarray) -> None:
        self.ee[idx] = EE_START
        self.tile[idx] = np.stack(
            [self._rng.uniform(0.0, 0.15, len(idx)), np.full(len(idx), 0.2), np.zeros(len(idx))], 1
        )
        self.holding[idx] = False
        self.picked[idx] = False
        self.t[idx] = 0
        self.frames[idx] = 0.0
        self.frames[idx, 0] = self._frame(idx)

    def _obs(self, idx: np.ndarray | None = None) -> np.ndarray:
        fr = self.frames if idx is None else self.frames[idx]
        return fr.reshape(len(fr), OBS_DIM).copy()

    def reset(self, *, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._reset_idx(np.arange(self.num_envs))
        return self._obs(), {}

    _STATE = ("ee", "tile", "holding", "picked", "t", "frames")

    def state(self) -> dict:
        """Every array of the envs and the RNG's state (plain data; see :meth:`restore`)."""
        st: dict = {k: getattr(self, k).copy() for k in self._STATE}
        st["rng"] = self._rng.bit_generator.state
        return st

    def restore(self, state: dict) -> np.ndarray:
        """Back to a :meth:`state` → the observations at that point."""
        for k in self._STATE:
            getattr(self, k)[...] = state[k]
        self._rng = np.random.default_rng()
        self._rng.bit_generator.state = state["rng"]
        return self._obs()

    def step(self, actions):
        a = np.clip(np.asarray(actions, np.float64), -1.0, 1.0)
        self.t += 1
        self.ee += STEP * a[:, 0:3]
        self.tile[self.holding] = self.ee[self.holding]
        suction = a[:, 6] >= 0.5
        drop = a[:, 6] <= -0.5
        r = np.zeros(self.num_envs, np.float32)
        near = np.linalg.norm(self.ee - self.tile, axis=1) < PICK_DIST
        pick = suction & near & ~self.picked
        self.holding |= pick
        self.picked |= pick
        r[pick] += 1.0
        fall = drop & self.holding
        installed = self.holding & (np.linalg.norm(self.tile - TARGET, axis=1) < INSTALL_DIST)
        r[installed] += 1.0
        r[fall & ~installed] -= 0.5
        terminated = installed | fall
        truncated = ~terminated & (self.t >= self.max_episode_steps)
        self.frames[:, 1:] = self.frames[:, :-1]
        self.frames[:, 0] = self._frame(np.arange(self.num_envs))
        obs = self._obs()
        infos: dict = {"picked": self.picked.copy(), "installed": installed.copy()}
        ended = terminated | truncated
        if ended.any():
            idx = np.flatnonzero(ended)
            final = np.empty(self.num_envs, dtype=object)
            for i in idx:
                final[i] = obs[i].copy()
            infos["final_obs"] = final
            infos["_final_obs"] = ended.copy()
            self._reset_idx(idx)
            obs[idx] = self._obs(idx)
        return obs, r, terminated, truncated, infos


def make_vec(num_envs: int, seed: int | None = None, max_episode_steps: int = 100) -> VectorEnv:
    return ToyTileVecEnv(num_envs, max_episode_steps=max_episode_steps, seed=seed)


def expert_demos(
    episodes: int, seed: int = 0, noise: float = 0.1, max_episode_steps: int = 100
) -> dict[str, np.ndarray]:
    """Scripted expert episodes, in the arrays of ``mimicrete.demos.load``."""
    env = ToyTileVecEnv(1, max_episode_steps=max_episode_steps, seed=seed)
    rng = np.random.default_rng(seed + 1)
    obs, _ = env.reset(seed=seed)
    rows: dict[str, list] = {k: [] for k in STEP_DTYPES}
    ep = 0
    while ep < episodes:
        goal = TARGET if env.holding[0] else env.tile[0]
        a = np.zeros(ACT_DIM)
        a[0:3] = np.clip((goal - env.ee[0]) / STEP + rng.normal(0, noise, 3), -1, 1)
        if not env.holding[0] and np.linalg.norm(env.ee[0] - env.tile[0]) < PICK_DIST * 0.75:
            a[6] = 1.0
        rows["obs"].append(obs[0])
        rows["actions"].append(a.astype(np.float32))
        obs, r, term, trunc, _ = env.step(a[None].astype(np.float32))
        rows["rewards"].append(r[0])
        rows["terminated"].append(term[0])
        rows["truncated"].append(trunc[0])
        rows["episode"].append(ep)
        if term[0] or trunc[0]:
            ep += 1
    return step_arrays(rows)


def toy_config(
    tmp: Path,
    *,
    max_steps=2048,
    buffer=512,
    batch=128,
    num_envs=8,
    ckpt=1024,
    gail=0.01,
    bc=0.5,
    survivor_bias="bootstrap",
    seed=0,
):
    """A tiny trainer config on the toy env with toy expert demos (written into ``tmp``);
    used by the tests and the trainer benchmark."""
    demos = tmp / "toy_demos.npz"
    if not demos.exists():
        np.savez(demos, **expert_demos(12, seed=5))
    rs: dict = {"extrinsic": {"gamma": 0.99, "strength": 1.0}}
    if gail:
        rs["gail"] = {
            "gamma": 0.99,
            "strength": gail,
            "learning_rate": 5e-4,
            "demo_path": str(demos),
            "survivor_bias": survivor_bias,
            "network_settings": {"normalize": True, "hidden_units": 32, "num_layers": 2},
        }
    b: dict = {
        "trainer_type": "ppo",
        "hyperparameters": {
            "batch_size": batch,
            "buffer_size": buffer,
            "learning_rate": 5e-4,
            "beta": 0.01,
            "epsilon": 0.2,
            "lambd": 0.95,
            "num_epoch": 2,
        },
        "network_settings": {"normalize": True, "hidden_units": 32, "num_layers": 2},
        "reward_signals": rs,
        "max_steps": max_steps,
        "time_horizon": 400,
        "summary_freq": buffer,
        "checkpoint_interval": ckpt,
        "keep_checkpoints": 3,
        "demo_episodes": 10,
    }
    if bc:
        b["behavioral_cloning"] = {"demo_path": str(demos), "strength": bc, "steps": max_steps}
    from mimicrete.learn.config import from_dict

    return from_dict(
        {
            "behaviors": {"Toy": b},
            "env_settings": {"env_id": "Toy-v0", "num_envs": num_envs, "seed": seed},
            "torch_settings": {"num_threads": 1},
        }
    )
