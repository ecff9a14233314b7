"""Gymnasium environments over the Rust simulator (``tile-sim``).

Ids (registered when this module is imported; see :func:`register_envs`):

* ``mimicrete/TileSuction-v0``: the paper's tile installation with a four-cup suction head.
* ``mimicrete/BlockGrip-v0``: pick and place a block with a parallel gripper.
* ``mimicrete/Screw-v0``: grip a nut and screw it down a bolt.

Spaces (all float32): observation ``Box(-inf, inf, (obs_dim,))`` = 5 stacked frames, oldest first,
zero-padded at episode start (TileSuction frame: 6 joint angles [rad], suction state ±1, cup centre
[m], target [m], tile centre [m]; Base frame, Z up). Action ``Box(-1, 1, (act_dim,))``: six joint
motions (× ``MAX_JOINT_STEP`` rad per step, clipped) and the end-effector command (≥0.5 suction /
close, ≤-0.5 drop / open, otherwise hold); Screw adds the spin command. Rewards are the paper's
sparse rewards (+1 pick, +1 install and terminate, -0.5 fall and terminate).

Time limit: the simulator itself truncates at 750 steps (``truncated=True``); the ids are
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
episode started.
"""

from __future__ import annotations

import operator
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from mimicrete import _native, tasks

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


START_KEYS = ("object_pose", "target_offset", "pad_offset")
_START_LENS = {"object_pose": 3, "target_offset": 2, "pad_offset": 2}


def _numbers(value: Any, what: str, n: int) -> list[float]:
    """``value`` as ``n`` finite floats, or a ValueError naming ``what``."""
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
    (``object_pose``, ``target_offset``, ``pad_offset``; per env lists when ``num_envs`` is
    given), ``{}`` when there is none. Shapes are checked here, naming the field; the
    simulator checks the table, the pad and the reach."""
    if not options or all(options.get(k) is None for k in START_KEYS):
        return {}
    if options.get("object_pose") is None:
        raise ValueError("target_offset / pad_offset need an object_pose [x, y, yaw]")
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


def _spaces(task: str) -> tuple[spaces.Box, spaces.Box]:
    t = tasks.get(task)
    obs = spaces.Box(-np.inf, np.inf, shape=(t.obs_dim,), dtype=np.float32)
    act = spaces.Box(-1.0, 1.0, shape=(t.act_dim,), dtype=np.float32)
    return obs, act


class MimicreteEnv(gym.Env):
    """One simulated UR3 task (see the module docstring for spaces and rewards)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": int(round(1.0 / CONTROL_DT))}

    def __init__(self, task: str = "TileSuction", render_mode: str | None = None) -> None:
        self.task = task_of(task)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.observation_space, self.action_space = _spaces(self.task)
        self._sim = _native.SimEnv(self.task, 0)
        self._scene = self._sim.scene()

    @property
    def sim(self) -> Any:
        """The underlying ``mimicrete._native.SimEnv`` (snapshots, scene, test teleports)."""
        return self._sim

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


class MimicreteVecEnv(VectorEnv):
    """``num_envs`` worlds of one task in the Rust ``VecEnv``; same-step auto-reset."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(
        self, task: str, num_envs: int, seed: int | None = None, num_threads: int | None = None
    ) -> None:
        self.task = task_of(task)
        self.num_envs = _count(num_envs, "num_envs")
        threads = _count(num_threads, "num_threads") if num_threads is not None else 2
        base = 0 if seed is None else _seed(seed)
        self._sim = _native.SimVecEnv(self.task, self.num_envs, base, threads)
        self.single_observation_space, self.single_action_space = _spaces(self.task)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._seed = seed
        self._rng = np.random.default_rng(seed)

    @property
    def sim(self) -> Any:
        """The underlying ``mimicrete._native.SimVecEnv``."""
        return self._sim

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


def make_vec(
    env_id: str, num_envs: int, seed: int | None = None, num_threads: int | None = None
) -> MimicreteVecEnv:
    """A ``gymnasium.vector.VectorEnv`` of ``num_envs`` worlds (env i starts episode ``seed + i``;
    later episodes: see the module docstring). ``num_envs`` and ``num_threads``: positive
    integers; ``seed``: None or an integer in [0, 2**64-1]; anything else is a ValueError."""
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


def register_envs() -> None:
    """Register the three ids with gymnasium (idempotent)."""
    entries = {
        "TileSuction": ("TileSuctionEnv", "make_tile_suction_vec"),
        "BlockGrip": ("BlockGripEnv", "make_block_grip_vec"),
        "Screw": ("ScrewEnv", "make_screw_vec"),
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


# ---------------------------------------------------------------- rendering (rgb_array)


def _quat_mat(q: Any) -> np.ndarray:
    x, y, z, w = (float(v) for v in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _frame(item: dict[str, Any], snap: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    fr = item["frame"]
    if fr == "world":
        return np.eye(3), np.zeros(3)
    if fr == "object":
        p = snap["object"]
    else:
        p = snap["links"][int(fr[4:])]
    return _quat_mat(p["q"]), np.asarray(p["t"], dtype=float)


def _cross2(u: np.ndarray, v: np.ndarray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def _hull(pts: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain) of 2-D points."""
    pts = np.unique(np.round(pts, 9), axis=0)
    if len(pts) <= 2:
        return pts
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]

    def half(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and _cross2(out[-1] - out[-2], p - out[-2]) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def render_rgb(
    scene: list[dict[str, Any]], snap: dict[str, Any], size: tuple[int, int] = (640, 320)
) -> np.ndarray:
    """Top (x-y) and side (x-z) orthographic drawing of the scene → ``(H, W, 3)`` uint8."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon

    fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2)
    views = [(0, 1, "top (x, y)"), (0, 2, "side (x, z)")]
    for ax, (_, j, title) in zip(axes, views, strict=True):
        ax.set_title(title, fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlim(-0.55, 0.45)
        ax.set_ylim(-0.15, 0.6) if j == 1 else ax.set_ylim(-0.1, 0.55)
        ax.tick_params(labelsize=6)
    for item in scene:
        if item["name"] == "table":
            continue
        rot, org = _frame(item, snap)
        local_r = _quat_mat(item["rotation"])
        local_t = np.asarray(item["translation"], dtype=float)
        color = tuple(item["rgba"][:3])
        alpha = float(item["rgba"][3])
        kind = item["kind"]
        if kind == "capsule":
            a = rot @ (local_r @ np.asarray(item["a"]) + local_t) + org
            b = rot @ (local_r @ np.asarray(item["b"]) + local_t) + org
            width = float(item["radius"]) * 2 * 100 * 1.0
            for ax, (i, j, _) in zip(axes, views, strict=True):
                ax.plot(
                    [a[i], b[i]],
                    [a[j], b[j]],
                    color=color,
                    lw=max(width, 1.0),
                    solid_capstyle="round",
                    alpha=alpha,
                )
            continue
        if kind == "box":
            h = np.asarray(item["half_extents"], dtype=float)
        else:
            r, hh = float(item["radius"]), float(item["half_height"])
            h = np.array([r, r, hh])
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
        world = (rot @ (local_r @ corners.T + local_t[:, None])).T + org
        for ax, (i, j, _) in zip(axes, views, strict=True):
            hull = _hull(world[:, [i, j]])
            if len(hull) >= 3:
                ax.add_patch(
                    Polygon(hull, closed=True, facecolor=color, edgecolor="k", lw=0.3, alpha=alpha)
                )
    axes[1].axhline(0.0, color=(0.45, 0.35, 0.25), lw=2)
    label = f"step {snap['step']}  held={snap['held']}  picked={snap['picked']}"
    fig.suptitle(label, fontsize=8)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    return img
