"""Reading a folder of MCAP demos for export: one task, every episode checked by replaying it.

Both exporters (:mod:`mimicrete.export.lerobot`, :mod:`mimicrete.export.minari`) read their input
here. :func:`read_demo_dir` loads every ``*.mcap`` of a directory (sorted by name; ``*.partial``
files are skipped, as :func:`mimicrete.demos.load` does), requires one task for all of them, and
replays each episode in the simulator from its seed with its recorded actions (a generated
demo, ``mimicrete demogen``, from the explicit start its metadata records: the seed's own start
moved there, as the demo curriculum replays it). The replay must
give back the recorded observations, rewards and terminations exactly (the simulator is
deterministic; on the 60 converted demos of the tests the difference is 0.0), and gives what the
demo file does not store: the observation after the last step (Minari keeps N + 1 observations
per episode) and the per-step ``picked`` / ``held`` / ``installed`` / ``fell`` flags (LeRobot's
``next.success`` is ``installed`` after the step).

The exported action carries the effector command as a level (:mod:`mimicrete.export.levels`,
docs/formats.md section 4), not as the demo's one-step switch; the replay steps the simulator with
the levels (as :func:`mimicrete.export.levels.to_env` hands them to the env), so every exported
episode is checked to give back its demo step for step.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import tasks
from mimicrete._native import MimicreteError
from mimicrete.demos import recorded_start
from mimicrete.export import levels

#: Names of one observation frame's floats per task (tile-sim's ``Task::obs_frame_dim`` layout).
_JOINTS = [f"q{i}" for i in range(6)]
_XYZ = ("x", "y", "z")
FRAME_NAMES: dict[str, list[str]] = {
    "suction": _JOINTS
    + ["suction"]
    + [f"cup_{a}" for a in _XYZ]
    + [f"target_{a}" for a in _XYZ]
    + [f"tile_{a}" for a in _XYZ],
    "grip": _JOINTS
    + ["gripper_width"]
    + [f"tcp_{a}" for a in _XYZ]
    + [f"target_{a}" for a in _XYZ]
    + [f"block_{a}" for a in _XYZ],
    "screw": _JOINTS
    + ["gripper_width", "spin"]
    + [f"tcp_{a}" for a in _XYZ]
    + [f"target_{a}" for a in _XYZ]
    + [f"nut_{a}" for a in _XYZ]
    + ["turns"],
}
#: The row's (TileRow, tile-sim ``task/tile_row.rs``): the suction task's for the current tile
#: (the one held, else the first not installed), its centre minus the cup's and its target minus
#: its centre, then per tile ``i`` its target, its centre and its installed flag.
_ROW_REL = [f"{w}_{a}" for w in ("tile_from_cup", "target_from_tile") for a in _XYZ]
_ROW_TILES = (tasks.get("row").obs_frame_dim - len(FRAME_NAMES["suction"]) - len(_ROW_REL)) // 7
FRAME_NAMES["row"] = [
    *FRAME_NAMES["suction"],
    *_ROW_REL,
    *(
        name
        for i in range(_ROW_TILES)
        for name in (*(f"target{i}_{a}" for a in _XYZ), *(f"tile{i}_{a}" for a in _XYZ))
        + (f"installed{i}",)
    ),
]

#: The placed tile's (TilePlace, tile-sim ``task/tile_place.rs``): the suction task's, the vacuum
#: switch, the two differences, the yaw error, the yaws as cos/sin of four times the angle, and the
#: fine gauge of the last millimetres.
FRAME_NAMES["place"] = [
    *FRAME_NAMES["suction"],
    "vacuum",
    *_ROW_REL,
    "yaw_error",
    "tile_cos4yaw",
    "tile_sin4yaw",
    "target_cos4yaw",
    "target_sin4yaw",
    *(f"target_from_tile_fine_{a}" for a in _XYZ),
    "yaw_error_fine",
]

#: Names of the exported action's entries per task: the effector command as a level
#: (:mod:`mimicrete.export.levels`; the layout before it named these ``suction_command`` /
#: ``gripper_command`` and held the demo's one-step switch).
ACTION_NAMES: dict[str, list[str]] = {
    "suction": [*(f"dq{i}" for i in range(6)), "suction_level"],
    "grip": [*(f"dq{i}" for i in range(6)), "gripper_level"],
    "screw": [*(f"dq{i}" for i in range(6)), "gripper_level", "spin_command"],
    "row": [*(f"dq{i}" for i in range(6)), "suction_level"],
    "place": [*(f"dq{i}" for i in range(6)), "suction_level"],
}

INFO_KEYS: tuple[str, ...] = ("picked", "held", "installed", "fell")


class ExportError(MimicreteError, ValueError):
    """Input that cannot be exported (mixed tasks, a damaged demo, an existing output, ...)."""


@dataclass
class DemoEpisode:
    """One demonstration, checked by replay. ``T`` steps."""

    file: str
    index: int  # position in the dataset (0, 1, ...)
    obs: np.ndarray  # (T, obs_dim) float32: the observation each action was chosen from
    actions: np.ndarray  # (T, act_dim) float32, exported: the effector command as a level
    rewards: np.ndarray  # (T,) float32
    terminated: np.ndarray  # (T,) bool
    truncated: np.ndarray  # (T,) bool
    final_obs: np.ndarray  # (obs_dim,) float32: the observation after the last step (replayed)
    info: dict[str, np.ndarray]  # INFO_KEYS -> (T,) bool, after each step (replayed)
    seed: int  # the simulator's episode seed (u64)
    success: bool
    #: the explicit start the episode was replayed from (``object_pose``, ``target_offset``, a
    #: turned pad's ``pad_yaw``: a generated demo's); None: the paper's start of ``seed``
    start: dict[str, Any] | None = None
    meta: dict[str, str] = field(default_factory=dict)
    #: (T, act_dim) float32: the actions as the demo recorded them (the effector's switches)
    recorded_actions: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.rewards.shape[0])


@dataclass
class DemoSet:
    """Every episode of one task, in file-name order."""

    task: str  # suction | grip | screw | row
    sim: str  # TileSuction | BlockGrip | Screw | TileRow
    env_id: str  # mimicrete/TileSuction-v0 ...
    control_dt: float
    obs_dim: int
    act_dim: int
    episodes: list[DemoEpisode]
    #: the task as one sentence (its spec's ``about.instruction``: LeRobot's task text)
    instruction: str = ""
    #: the task spec file the demos were recorded in (None: the built-in task)
    task_file: str | None = None

    @property
    def num_frames(self) -> int:
        return sum(len(e) for e in self.episodes)

    @property
    def fps(self) -> int:
        return int(round(1.0 / self.control_dt))


def demo_files(demos_dir: str | os.PathLike[str]) -> list[Path]:
    """The ``*.mcap`` entries of a directory, sorted by name (``*.partial`` never match), as
    :func:`mimicrete.demos.files` lists them: one that cannot be read (a dangling symbolic link)
    is refused when it is read, not left out."""
    from mimicrete import demos

    d = Path(demos_dir)
    if not d.exists():
        raise ExportError(f"{d}: no such directory")
    if not d.is_dir():
        raise ExportError(f"{d}: not a directory (give the folder of the demos)")
    files = demos.files(d)
    if not files:
        raise ExportError(f"{d}: no *.mcap demos")
    return files


def read_demo_dir(demos_dir: str | os.PathLike[str]) -> DemoSet:
    """Every demo of ``demos_dir``, all of one task, each replayed and checked.

    Raises :class:`ExportError` with one line naming the file for: no demos, a file that cannot
    be read (cut, damaged, not a demo: ``mimicrete.demos.salvage_to`` repairs a cut one), a file
    that was never finished, demos of more than one task, and an episode whose replay does not
    give back its recorded observations.
    """
    from mimicrete import LogFormatError, demos, tasks

    files = demo_files(demos_dir)
    raw: list[tuple[Path, dict[str, Any]]] = []
    for f in files:
        try:
            ep = demos.read(f)
        except (LogFormatError, OSError, ValueError) as e:
            raise ExportError(
                f"{f}: damaged demo ({e}); `mimicrete inspect` shows what is in it"
            ) from None
        meta = {str(k): str(v) for k, v in dict(ep["meta"]).items()}
        if "task" not in meta:
            raise ExportError(f"{f}: no task in its metadata (not a mimicrete demo?)")
        if "success" not in meta:
            raise ExportError(f"{f}: unfinished demo (no 'episode' metadata record)")
        raw.append((f, {**ep, "meta": meta}))

    by_task: dict[str, list[str]] = {}
    for f, ep in raw:
        by_task.setdefault(ep["meta"]["task"], []).append(f.name)
    if len(by_task) > 1:
        parts = [
            f"{t}: {len(n)} ({', '.join(n[:2])}{', ...' if len(n) > 2 else ''})"
            for t, n in sorted(by_task.items())
        ]
        raise ExportError(
            f"{Path(demos_dir)}: demos of {len(by_task)} tasks ({'; '.join(parts)}); "
            "a dataset holds one task: put each task's demos in its own folder"
        )
    task_name = next(iter(by_task))
    try:
        spec = tasks.get(task_name)
    except ValueError as e:
        raise ExportError(f"{files[0]}: {e}") from None
    task_file, about = _recorded_spec(Path(demos_dir), raw, spec)

    control_dt = {float(ep["meta"].get("control_dt", "nan")) for _, ep in raw}
    if len(control_dt) != 1 or not all(np.isfinite(list(control_dt))):
        raise ExportError(f"{Path(demos_dir)}: demos disagree on control_dt ({sorted(control_dt)})")

    episodes = []
    for i, (f, ep) in enumerate(raw):
        obs = np.asarray(ep["obs"], dtype=np.float32)
        act = np.asarray(ep["actions"], dtype=np.float32)
        if len(act) == 0:
            raise ExportError(f"{f}: demo has no steps")
        if obs.shape[1:] != (spec.obs_dim,) or act.shape[1:] != (spec.act_dim,):
            raise ExportError(
                f"{f}: obs/action sizes {obs.shape[1:]}/{act.shape[1:]} do not match task "
                f"{spec.name} ({spec.obs_dim}/{spec.act_dim})"
            )
        seed = int(ep["meta"].get("seed", "0"))
        start = recorded_start(ep["meta"])
        level = levels.to_levels(spec.name, act)
        final_obs, info = _replay_levels(f, spec, seed, obs, act, level, ep, task_file, start)
        episodes.append(
            DemoEpisode(
                file=str(f),
                index=i,
                obs=obs,
                actions=level,
                recorded_actions=act,
                rewards=np.asarray(ep["rewards"], dtype=np.float32),
                terminated=np.asarray(ep["terminated"], dtype=bool),
                truncated=np.asarray(ep["truncated"], dtype=bool),
                final_obs=final_obs,
                info=info,
                seed=seed,
                success=ep["meta"]["success"] == "true",
                start=start,
                meta=ep["meta"],
            )
        )
    return DemoSet(
        task=spec.name,
        sim=spec.sim,
        env_id=spec.env_id,
        control_dt=control_dt.pop(),
        obs_dim=spec.obs_dim,
        act_dim=spec.act_dim,
        episodes=episodes,
        instruction=about["instruction"],
        task_file=task_file,
    )


def _recorded_spec(
    demos_dir: Path, raw: list[tuple[Path, dict[str, Any]]], task: Any
) -> tuple[str | None, dict[str, str]]:
    """The task spec file the demos were recorded in (None: the built-in task) and its ``about``
    section. The demos must share one spec (``task_spec``, none: the built-in one) and its file
    must still hold it: the replay runs there."""
    recorded = {ep["meta"].get("task_spec") for _, ep in raw}
    if len(recorded) > 1:
        n = sum(1 for _, ep in raw if ep["meta"].get("task_spec") is None)
        raise ExportError(
            f"{demos_dir}: demos recorded in {len(recorded)} task specs ({n} in the built-in "
            "one); a dataset holds one: put each spec's demos in its own folder"
        )
    from mimicrete import tasks

    raw_spec = recorded.pop()
    if raw_spec is None:
        return None, task.builtin_spec()["about"]
    f, ep = raw[0]
    path = ep["meta"].get("task_file", "")
    try:
        spec_task, spec = tasks.load_task_file(path)
    except (OSError, ValueError) as e:
        raise ExportError(f"{f}: task file {tasks.task_file_error(path, e)}") from None
    if json.loads(json.dumps(spec, sort_keys=True)) != json.loads(raw_spec):
        raise ExportError(
            f"{f}: task file {path} is not the spec the demo was recorded in (it changed since)"
        )
    if spec_task.name != task.name:
        raise ExportError(f"{f}: task file {path} runs {spec_task.name}, the demo is {task.name}")
    return path, spec["about"]


def _replay_levels(
    f: Path,
    spec: Any,
    seed: int,
    obs: np.ndarray,
    recorded: np.ndarray,
    level: np.ndarray,
    ep: dict[str, Any],
    task_file: str | None,
    start: dict[str, Any] | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """:func:`_replay` of the exported actions (the levels as the env takes them). Where they do
    not give back the demo, the recorded actions are replayed too, to say which fails: the demo
    (another simulator), or its level (the effector did not read its command as a latch)."""
    try:
        return _replay(f, spec.sim, seed, obs, levels.to_env(level, ACTION_NAMES[spec.name]), ep,
                       task_file, start)  # fmt: skip
    except ExportError as e:
        _replay(f, spec.sim, seed, obs, recorded, ep, task_file, start)  # raises: a foreign demo
        why = str(e).removeprefix(f"{f}: ")
        raise ExportError(
            f"{f}: its recorded actions replay, its effector command as a level does not "
            f"(docs/formats.md section 4): {why}"
        ) from None


def _replay(
    f: Path,
    sim: str,
    seed: int,
    obs: np.ndarray,
    act: np.ndarray,
    ep: dict[str, Any],
    task_file: str | None = None,
    start: dict[str, Any] | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Step a fresh simulator (of ``task_file`` if given) reset with ``seed`` (at ``start``, a
    generated demo's explicit start, when given) through ``act``; check it reproduces the demo;
    return the observation after the last step and the per-step info flags."""
    from mimicrete import _native

    env = _native.SimEnv(sim) if task_file is None else _native.SimEnv.from_spec_file(task_file, 0)
    where = f"seed {seed}" if start is None else f"seed {seed} at its recorded start"
    try:
        o = np.asarray(env.reset(seed, **(start or {})), dtype=np.float32)
    except (TypeError, ValueError) as e:  # a start the simulator refuses (off the table, ...)
        raise ExportError(f"{f}: cannot start the replay at its recorded start ({e})") from None
    info = {k: np.zeros(len(act), dtype=bool) for k in INFO_KEYS}
    rewards = np.asarray(ep["rewards"], dtype=np.float32)
    term = np.asarray(ep["terminated"], dtype=bool)
    trunc = np.asarray(ep["truncated"], dtype=bool)
    for k in range(len(act)):
        if not np.array_equal(o, obs[k]):
            diff = float(np.max(np.abs(o - obs[k])))
            raise ExportError(
                f"{f}: replaying its actions from {where} gives another observation at step "
                f"{k} (max difference {diff:.3g}); the demo does not match this simulator"
            )
        o, r, te, tr, inf = env.step(act[k])
        o = np.asarray(o, dtype=np.float32)
        if np.float32(r) != rewards[k] or bool(te) != term[k] or bool(tr) != trunc[k]:
            raise ExportError(
                f"{f}: replay gives reward/terminated/truncated {r}/{te}/{tr} at step {k}, the "
                f"demo {rewards[k]}/{term[k]}/{trunc[k]}; the demo does not match this simulator"
            )
        for key in INFO_KEYS:
            info[key][k] = bool(inf[key])
        if (te or tr) and k != len(act) - 1:
            raise ExportError(f"{f}: the episode ends at step {k} but the demo goes on")
    return o, info


def check_new_output(out: str | os.PathLike[str]) -> Path:
    """The output path, which must not exist yet (its parent is created if missing)."""
    p = Path(out)
    if p.exists() or p.is_symlink():
        raise ExportError(f"--out {p}: exists already; give a new directory")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ExportError(f"--out {p}: {e.strerror or e}") from None
    return p
