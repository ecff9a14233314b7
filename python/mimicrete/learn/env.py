"""The environments the trainer and the evaluation run: which vector env an ``env_id`` names, and
the terminal observations of the episodes that ended in a step.

``Toy...`` ids give the pure-numpy stand-in of ``mimicrete.testing.toyenv`` (tests, smoke runs);
anything else is ``mimicrete.envs.make_vec`` over the Rust simulator. Both follow gymnasium 1.x's
SAME_STEP autoreset: when an episode ends at a step, ``infos["final_obs"]`` holds its last
observation and the returned observation is already the next episode's first.
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: continuous action components (six joint motions); every entry after them is a command branch,
#: a categorical choice in {-1, 0, 1}: the end effector (suction / grip), and for Screw the spin
N_CONT = 6
TOY_PREFIX = "Toy"


def make_env(env_id: str, num_envs: int, seed: int, task_file: str | None = None) -> Any:
    """``num_envs`` vectorised envs of ``env_id`` seeded with ``seed`` (``Task-v0``: of the task
    spec file ``task_file``)."""
    if env_id.startswith(TOY_PREFIX):
        from mimicrete.testing import toyenv

        return toyenv.make_vec(num_envs, seed=seed)
    from mimicrete import envs

    if task_file is not None:
        return envs.make_vec(env_id, num_envs=num_envs, seed=seed, spec=task_file)
    return envs.make_vec(env_id, num_envs=num_envs, seed=seed)


def sim_task_of(env_id: str, task_file: str | None = None) -> str | None:
    """The simulator task (``TileSuction``, ``BlockGrip``, ``Screw``) an env id runs (``Task-v0``:
    the one the spec file ``task_file`` runs); None for the toy env."""
    if env_id.startswith(TOY_PREFIX):
        return None
    from mimicrete import tasks

    if task_file is not None:
        return tasks.load_task_file(task_file)[0].sim
    try:
        return tasks.get(env_id).sim
    except ValueError:
        return None


def command_branches(env: Any) -> int:
    """The number of command branches of a vector env's action (act_dim - :data:`N_CONT`)."""
    act_dim = int(env.single_action_space.shape[0])
    if act_dim <= N_CONT:
        raise ValueError(f"action of {act_dim} dims: expected {N_CONT} joint motions + commands")
    return act_dim - N_CONT


def final_obs_of(infos: dict, ended: np.ndarray) -> np.ndarray:
    """(k, D) terminal observations of the envs where ``ended`` (gymnasium 1.x SAME_STEP)."""
    fo = infos["final_obs"]
    idx = np.flatnonzero(ended)
    if isinstance(fo, np.ndarray) and fo.dtype != object:
        return fo[idx].astype(np.float32)
    return np.stack([np.asarray(fo[i], np.float32) for i in idx])
