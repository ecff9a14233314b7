"""Gymnasium environments over the Rust simulator (``tile-sim``).

Ids (registered when this module is imported; see :func:`register_envs`):

* ``mimicrete/TileSuction-v0``: the paper's tile installation with a four-cup suction head.
* ``mimicrete/BlockGrip-v0``: pick and place a block with a parallel gripper.
* ``mimicrete/Screw-v0``: grip a nut and screw it down a bolt.
* ``mimicrete/TileRow-v0``: install a row of three tiles, one after another, on a row of three
  pads with the suction head (issue 26 §2; ``crates/tile-sim/tasks/tile_row.toml``).
* ``mimicrete/TilePlace-v0``: the tile installation under rules a real cell keeps (a cup holds
  only sealed on the face, the held tile still collides, success = placed square within 5 mm;
  issue 46, ``crates/tile-sim/tasks/tile_place.toml``).
* ``mimicrete/Task-v0``: the task a spec file describes, ``gym.make("mimicrete/Task-v0",
  spec="my_task.toml")`` (tile-sim's task spec, version 1: ``crates/tile-sim/tasks/*.toml`` are the
  four above); its spaces are the sizes of the env the spec builds. ``make_vec("Task-v0", n,
  seed, spec=PATH)`` and ``gym.make_vec("mimicrete/Task-v0", n, vectorization_mode=
  "vector_entry_point", spec=PATH)`` give the vector env. A bad spec raises
  ``mimicrete.SimInputError`` (a ``ValueError``) with its ``field``, ``value`` and ``reason``.

Spaces (all float32): observation ``Box(-inf, inf, (obs_dim,))`` = 5 stacked frames, oldest first,
zero-padded at episode start (TileSuction frame: 6 joint angles [rad], suction state ±1, cup centre
[m], target [m], tile centre [m]; Base frame, Z up). Action ``Box(-1, 1, (act_dim,))``: six joint
motions (× the joint step, clipped: ``MAX_JOINT_STEP`` = 0.04 rad per step, or a task spec's
``robot.joint_step``, ``env.unwrapped.joint_step``), or in a spec with ``robot.action = "tool"``
(TilePlace) the TCP's motion and turn in Base (× ``robot.tool_step`` m, ``robot.tool_turn`` rad;
``SimEnv.action_toward`` gives the action towards joint angles), and the end-effector command
(≥0.5 suction / close, ≤-0.5 drop / open, otherwise hold); Screw adds the spin command. Rewards
are the paper's sparse rewards (+1 pick, +1 install and terminate, -0.5 fall and terminate).
TileRow's frame holds, after the suction state and the cup centre, each tile's target, centre
and installed flag (1 or 0); each tile's first pick and its install pay +1, the last install
terminates, and ``info["installed"]`` is that last install (the row complete).

Time limit: the simulator itself truncates at the spec's ``episode.max_steps`` (750 for
TileSuction, BlockGrip and Screw, 2000 for TileRow) (``truncated=True``); the ids are
registered without ``max_episode_steps`` so no ``TimeLimit`` wrapper counts a second time.

``make_vec(env_id, num_envs, seed)`` returns a :class:`gymnasium.vector.VectorEnv` backed by the
Rust ``VecEnv`` (all worlds stepped in one call across threads, interpreter lock released), with
``metadata["autoreset_mode"] = AutoresetMode.SAME_STEP``: an env that ends is reset in the same
call, its row of ``obs`` is the new episode's first observation and ``infos["final_obs"]`` (object
array, masked by ``infos["_final_obs"]``) holds the terminal one, ``infos["final_info"]`` its info.
``reset(options={"reset_mask": mask})`` resets only the masked envs.

Seeds: every episode's seed is a pure function of the base seed, the env index and the env's
episode count, tile-sim's ``episode_seed(base, i, k)``: ``base + i`` for the first episode,
SplitMix64 of (base, i, k) for the ``k``-th auto-reset (or masked reset). ``make_vec(seed=s)`` and
``reset(seed=s)`` set the base to ``s`` and the counts to 0, so a used vector env reset with ``s``
follows the same trajectories, auto-resets included, as a fresh one (gymnasium's contract).
``reset()`` without a seed draws the next base from the env's RNG (itself seeded by the last seed).
``state()`` / ``restore(state)`` save and rebuild the envs mid-episode exactly (the running
episodes' actions are replayed; the simulator is deterministic): what a trainer checkpoints.

Starts: episodes start as the paper's do (tile x uniform in [0, 0.15] m, the target fixed) unless
``sim.set_variation(starts="wide")`` (or ``"robust"``) widens them; tile-sim's ``starts`` module
documents the three. An explicit start: ``reset(options={"object_pose": [x, y, yaw],
"target_offset": [dx, dy]})`` (m, rad, Base frame; the pad moves with the target), on the vector
env one list per env. A start off the table, on the pad or out of reach is refused with a
``ValueError`` naming the field. ``info["start"]`` (single env) and ``sim.start(i)`` say where an
episode started; ``sim.last_placement()`` (single env) and ``sim.last_placement(i)`` where its last
finished episode left the object, as a tiler would check it (held, height above rest, xy and yaw
error, the lip-to-face gap of each hold; None for Screw), kept through the same-step reset.
"""

from __future__ import annotations

import operator
import os
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from mimicrete import _native, tasks
from mimicrete.render import render_rgb

TASKS = tasks.SIM_TASKS
ENV_IDS = tasks.ENV_IDS

FRAME_STACK = tasks.FRAME_STACK
MAX_EPISODE_STEPS = tasks.MAX_EPISODE_STEPS
CONTROL_DT = tasks.CONTROL_DT
MAX_JOINT_STEP = tasks.MAX_JOINT_STEP


def task_of(env_id: str) -> str:
    """Simulator task name of an env id: ``"mimicrete/TileSuction-v0"``, ``"TileSuction-v0"``,
    ``"TileSuction"`` or ``"suction"`` → ``"TileSuction"`` (:func:`mimicrete.tasks.get`)."""
    try:
        return tasks.get(env_id).sim
    except ValueError:
        raise ValueError(
            f"unknown env id {env_id!r}: expected one of {', '.join(ENV_IDS)}"
        ) from None


SEED_MAX = 2**64 - 1


def _integer(value: Any, what: str, expected: str) -> int:
    """``value`` as an int (bools and non-integral numbers refused), or a ValueError
    ``"{what} must be {expected}, got …"`` naming its value and type."""
    try:
        if isinstance(value, bool):
            raise TypeError
        return operator.index(value)
    except TypeError:
        raise ValueError(
            f"{what} must be {expected}, got {value!r} ({type(value).__name__})"
        ) from None


def _seed(seed: Any, what: str = "seed") -> int:
    """``seed`` as a u64, or a ValueError naming it and the range [0, 2**64-1]."""
    s = _integer(seed, what, "an integer in [0, 2**64-1]")
    if not 0 <= s <= SEED_MAX:
        raise ValueError(f"{what} must be an integer in [0, 2**64-1], got {s}")
    return s


def _count(value: Any, what: str) -> int:
    """A positive integer (bools and non-integral numbers refused), or a ValueError naming it."""
    n = _integer(value, what, "a positive integer")
    if n < 1:
        raise ValueError(f"{what} must be at least 1, got {n}")
    return n


START_KEYS = ("object_pose", "target_offset", "pad_offset", "pad_yaw")
#: numbers per key (0: one number, not a list: the pad's yaw in rad)
_START_LENS = {"object_pose": 3, "target_offset": 2, "pad_offset": 2, "pad_yaw": 0}


def _numbers(value: Any, what: str, n: int) -> list[float] | float:
    """``value`` as ``n`` finite floats (``n == 0``: one float, not a list), or a ValueError
    naming ``what``."""
    if n == 0:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise ValueError(f"{what} must be a number, got {value!r}")
        if not np.isfinite(value):
            raise ValueError(f"{what} must be finite, got {value!r}")
        return float(value)
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be {n} numbers, got {value!r}") from None
    if a.shape != (n,):
        raise ValueError(f"{what} must be {n} numbers, got {value!r}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite, got {value!r}")
    return [float(v) for v in a]


def start_options(options: dict[str, Any] | None, num_envs: int | None = None) -> dict[str, Any]:
    """The explicit start in reset ``options`` as keyword arguments of the simulator's reset
    (``object_pose``, ``target_offset``, ``pad_offset``, ``pad_yaw``; per env lists when
    ``num_envs`` is given), ``{}`` when there is none. Shapes are checked here, naming the
    field; the simulator checks the table, the pad and the reach."""
    if not options or all(options.get(k) is None for k in START_KEYS):
        return {}
    if options.get("object_pose") is None:
        raise ValueError("target_offset / pad_offset / pad_yaw need an object_pose [x, y, yaw]")
    out: dict[str, Any] = {}
    for key in START_KEYS:
        v = options.get(key)
        if v is None:
            continue
        n = _START_LENS[key]
        if num_envs is None:
            out[key] = _numbers(v, key, n)
            continue
        if not isinstance(v, (list, tuple, np.ndarray)) or len(v) != num_envs:
            raise ValueError(f"{key} must be a list of {num_envs} entries (one per env), got {v!r}")
        out[key + "s"] = [_numbers(e, f"{key}[{i}]", n) for i, e in enumerate(v)]
    return out


def _spaces(sim: Any) -> tuple[spaces.Box, spaces.Box]:
    """The observation and action spaces of a built simulator env (its ``obs_dim``, ``act_dim``),
    or of a built-in task named by ``sim`` (a string: :func:`mimicrete.tasks.get`)."""
    dims = tasks.get(sim) if isinstance(sim, str) else sim
    obs = spaces.Box(-np.inf, np.inf, shape=(int(dims.obs_dim),), dtype=np.float32)
    act = spaces.Box(-1.0, 1.0, shape=(int(dims.act_dim),), dtype=np.float32)
    return obs, act


TASK_FILE_ID = "mimicrete/Task-v0"


def _spec_path(spec: Any) -> str:
    """The task spec file ``spec`` names (a path), or a ValueError saying the id needs one."""
    if spec is None:
        raise ValueError(f"{TASK_FILE_ID} needs spec=PATH, a task spec file (TOML, version 1)")
    if not isinstance(spec, (str, os.PathLike)):
        raise ValueError(f"spec must be the path of a task spec file, got {spec!r}")
    return os.fspath(spec)


class MimicreteEnv(gym.Env):
    """One simulated UR3 task (see the module docstring for spaces and rewards)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": int(round(1.0 / CONTROL_DT))}

    def __init__(
        self, task: str = "TileSuction", render_mode: str | None = None, *, spec: Any = None
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        #: the task spec file this env runs (None: the built-in spec of ``task``)
        self.task_file = None if spec is None else _spec_path(spec)
        if self.task_file is None:
            self._sim = _native.SimEnv(task_of(task), 0)
        else:
            self._sim = _native.SimEnv.from_spec_file(self.task_file, 0)
        self.task: str = self._sim.task  # the task logic (TileSuction, ..., TileRow)
        self.observation_space, self.action_space = _spaces(self._sim)
        self._scene = self._sim.scene()

    @property
    def task_spec(self) -> dict[str, Any]:
        """The task spec this env runs, as a dict (tile-sim's ``TaskSpec``)."""
        return self._sim.spec()

    @property
    def sim(self) -> Any:
        """The underlying ``mimicrete._native.SimEnv`` (snapshots, scene, test teleports)."""
        return self._sim

    @property
    def joint_step(self) -> float:
        """Joint motion (rad) per step at full action: the spec's ``robot.joint_step``, else
        ``MAX_JOINT_STEP``."""
        return float(self._sim.joint_step)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        # The episode seed comes from the gymnasium RNG, so reset(seed=s) fixes the episode and
        # every later reset() of the same env. options={"episode_seed": s} starts the simulator's
        # episode s instead (a recorded demo's seed: `mimicrete export --format minari` stores it
        # as each episode's reset options); the RNG still advances, so later resets do not change.
        episode_seed = int(self.np_random.integers(0, 2**63 - 1))
        if options and options.get("episode_seed") is not None:
            episode_seed = int(options["episode_seed"])
            if not 0 <= episode_seed < 2**64:
                raise ValueError(f"episode_seed must be a u64, got {episode_seed}")
        obs = self._sim.reset(episode_seed, **start_options(options))
        self._scene = self._sim.scene()
        info = {
            "episode_seed": episode_seed,
            "start": self._sim.start(),
            "picked": False,
            "installed": False,
            "fell": False,
        }
        return obs, info

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        a = np.asarray(action, dtype=np.float32)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError("action holds a NaN or an infinity")
        obs, reward, terminated, truncated, info = self._sim.step(a)
        return obs, float(reward), bool(terminated), bool(truncated), info

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        return render_rgb(self._scene, self._sim.snapshot())


class TileSuctionEnv(MimicreteEnv):
    def __init__(self, render_mode: str | None = None) -> None:
        super().__init__("TileSuction", render_mode)


class BlockGripEnv(MimicreteEnv):
    def __init__(self, render_mode: str | None = None) -> None:
        super().__init__("BlockGrip", render_mode)


class ScrewEnv(MimicreteEnv):
    def __init__(self, render_mode: str | None = None) -> None:
        super().__init__("Screw", render_mode)


class TileRowEnv(MimicreteEnv):
    def __init__(self, render_mode: str | None = None) -> None:
        super().__init__("TileRow", render_mode)


class TilePlaceEnv(MimicreteEnv):
    def __init__(self, render_mode: str | None = None) -> None:
        super().__init__("TilePlace", render_mode)


class TaskEnv(MimicreteEnv):
    """``mimicrete/Task-v0``: the task the spec file ``spec`` describes."""

    def __init__(self, spec: Any = None, render_mode: str | None = None) -> None:
        super().__init__(render_mode=render_mode, spec=_spec_path(spec))


class MimicreteVecEnv(VectorEnv):
    """``num_envs`` worlds of one task in the Rust ``VecEnv``; same-step auto-reset."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(
        self,
        task: str | None,
        num_envs: int,
        seed: int | None = None,
        num_threads: int | None = None,
        *,
        spec: Any = None,
    ) -> None:
        self.num_envs = _count(num_envs, "num_envs")
        threads = _count(num_threads, "num_threads") if num_threads is not None else 2
        base = 0 if seed is None else _seed(seed)
        #: the task spec file these envs run (None: the built-in spec of ``task``)
        self.task_file = None if spec is None else _spec_path(spec)
        if self.task_file is None:
            self._sim = _native.SimVecEnv(task_of(str(task)), self.num_envs, base, threads)
        else:
            make = _native.SimVecEnv.from_spec_file
            self._sim = make(self.task_file, self.num_envs, base, threads)
        self.task: str = self._sim.task
        self.single_observation_space, self.single_action_space = _spaces(self._sim)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._seed = seed
        self._rng = np.random.default_rng(seed)

    @property
    def sim(self) -> Any:
        """The underlying ``mimicrete._native.SimVecEnv``."""
        return self._sim

    @property
    def task_spec(self) -> dict[str, Any]:
        """The task spec these envs run, as a dict."""
        return self._sim.spec()

    @property
    def joint_step(self) -> float:
        """Joint motion (rad) per step at full action (as :attr:`MimicreteEnv.joint_step`)."""
        return float(self._sim.joint_step)

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        options = options or {}
        mask = options.get("reset_mask")
        if mask is not None:
            if seed is not None:
                raise ValueError(
                    "reset with a reset_mask takes no seed (masked envs start their next "
                    "episode of the current base seed)"
                )
            m = np.asarray(mask, dtype=bool)
            if m.shape != (self.num_envs,):
                raise ValueError(f"reset_mask must have shape ({self.num_envs},), got {m.shape}")
            return self._sim.reset_mask(m), {}
        starts = start_options(options, self.num_envs)
        if isinstance(seed, (list, tuple, np.ndarray)):
            seeds = [_seed(s, "seed list entry") for s in seed]
            if len(seeds) != self.num_envs or any(s != seeds[0] + i for i, s in enumerate(seeds)):
                raise ValueError("a seed list must hold num_envs consecutive seeds [s, s+1, ...]")
            seed = seeds[0]
        if seed is not None:
            base = _seed(seed)
            self._rng = np.random.default_rng(base)
        else:
            base = int(self._rng.integers(0, 2**62))
        if starts:
            return self._sim.reset_starts(base, **starts), {}
        return self._sim.reset(base), {}

    def state(self) -> dict[str, Any]:
        """Plain data (ints, numpy arrays) that :meth:`restore` rebuilds this env from exactly:
        base seed, each env's episode count, where and with which actions its running episode
        started and went (``starts``: rows of x, y, yaw, target dx, dy, pad dx, dy), and the
        RNG that seedless ``reset()`` draws from. Teleports through ``sim`` are not included."""
        st = self._sim.state()
        st["rng"] = self._rng.bit_generator.state
        return st

    def restore(self, state: dict[str, Any]) -> np.ndarray:
        """Rebuild every env from :meth:`state` (the running episodes are replayed) → the
        observations ``(num_envs, obs_dim)``, equal to those when the state was taken."""
        obs = self._sim.restore(
            _seed(state["base_seed"], "base_seed"),
            [int(e) for e in state["episodes"]],
            [int(x) for x in state["seeds"]],
            [np.asarray(a, np.float32) for a in state["actions"]],
            None
            if state.get("starts") is None
            else np.asarray(state["starts"], np.float32).tolist(),
        )
        self._rng = np.random.default_rng()
        self._rng.bit_generator.state = state["rng"]
        return obs

    def reset_replay(
        self, i: int, seed: int, actions: Any, start: dict[str, Any] | None = None
    ) -> np.ndarray:
        """Reset env ``i`` alone to episode ``seed`` and replay ``actions`` (k, act_dim) in it: the
        state a recorded episode (a demo: its seed and actions) had after k steps. The episode
        starts at ``start`` (``{"object_pose": …, "target_offset": …}``, a demo's recorded start)
        or, without one, at the paper's start of ``seed`` (where demos are recorded), whatever
        variation the env draws from. The other envs do not move. Returns env ``i``'s
        observation (obs_dim,). Raises ``ValueError`` when the episode would end inside the
        replay, the start is refused or ``i`` is out of range."""
        a = np.asarray(actions, dtype=np.float32).reshape(-1, self.single_action_space.shape[0])
        return self._sim.reset_replay(int(i), int(seed), a, **start_options(start))

    def step(
        self, actions: Any
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        a = np.asarray(actions, dtype=np.float32)
        if a.shape != self.action_space.shape:
            raise ValueError(f"actions must have shape {self.action_space.shape}, got {a.shape}")
        obs, rew, term, trunc, final_obs, has_final, picked, installed, fell = self._sim.step(a)
        ones = np.ones(self.num_envs, dtype=bool)
        infos: dict[str, Any] = {
            "picked": picked,
            "_picked": ones,
            "installed": installed,
            "_installed": ones,
            "fell": fell,
            "_fell": ones,
        }
        if has_final.any():
            fo = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(has_final):
                fo[i] = final_obs[i]
            infos["final_obs"] = fo
            infos["_final_obs"] = has_final.copy()
            infos["final_info"] = {
                "picked": picked,
                "_picked": has_final.copy(),
                "installed": installed,
                "_installed": has_final.copy(),
                "fell": fell,
                "_fell": has_final.copy(),
            }
            infos["_final_info"] = has_final.copy()
        return obs, rew, term, trunc, infos


def _is_task_file_id(env_id: str) -> bool:
    return str(env_id).split("/")[-1].lower() in ("task-v0", "task")


def make_vec(
    env_id: str,
    num_envs: int,
    seed: int | None = None,
    num_threads: int | None = None,
    *,
    spec: Any = None,
) -> MimicreteVecEnv:
    """A ``gymnasium.vector.VectorEnv`` of ``num_envs`` worlds (env i starts episode ``seed + i``;
    later episodes: see the module docstring). ``num_envs`` and ``num_threads``: positive
    integers; ``seed``: None or an integer in [0, 2**64-1]; anything else is a ValueError.
    ``env_id`` ``"Task-v0"`` runs the task spec file ``spec`` (and only it takes one)."""
    if _is_task_file_id(env_id):
        return MimicreteVecEnv(None, num_envs, seed, num_threads, spec=_spec_path(spec))
    if spec is not None:
        raise ValueError(f"spec= goes with {TASK_FILE_ID}, not {env_id!r}")
    return MimicreteVecEnv(task_of(env_id), num_envs, seed, num_threads)


def _vector_entry(task: str):
    def make(
        num_envs: int = 1, seed: int | None = None, num_threads: int | None = None, **_: Any
    ) -> MimicreteVecEnv:
        return MimicreteVecEnv(task, num_envs, seed, num_threads)

    return make


make_tile_suction_vec = _vector_entry("TileSuction")
make_block_grip_vec = _vector_entry("BlockGrip")
make_screw_vec = _vector_entry("Screw")
make_tile_row_vec = _vector_entry("TileRow")
make_tile_place_vec = _vector_entry("TilePlace")


def make_task_file_vec(
    num_envs: int = 1,
    seed: int | None = None,
    num_threads: int | None = None,
    spec: Any = None,
    **_: Any,
) -> MimicreteVecEnv:
    """The vector entry point of ``mimicrete/Task-v0``."""
    return MimicreteVecEnv(None, num_envs, seed, num_threads, spec=_spec_path(spec))


def register_envs() -> None:
    """Register the five tasks' ids and ``mimicrete/Task-v0`` with gymnasium (idempotent)."""
    entries = {
        "TileSuction": ("TileSuctionEnv", "make_tile_suction_vec"),
        "BlockGrip": ("BlockGripEnv", "make_block_grip_vec"),
        "Screw": ("ScrewEnv", "make_screw_vec"),
        "TileRow": ("TileRowEnv", "make_tile_row_vec"),
        "TilePlace": ("TilePlaceEnv", "make_tile_place_vec"),
        "Task": ("TaskEnv", "make_task_file_vec"),
    }
    for task, (cls, vec) in entries.items():
        env_id = f"mimicrete/{task}-v0"
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point=f"mimicrete.envs:{cls}",
            vector_entry_point=f"mimicrete.envs:{vec}",
            max_episode_steps=None,
        )


register_envs()
