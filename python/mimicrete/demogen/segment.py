"""Object-centric segments of a recorded demo and their transform to a new start (MimicGen).

A demo has two subtasks split at its effector switch (the first step whose recorded end-effector
command, ``a[6] ≥ 0.5``, turns the suction on or closes the gripper): **approach + grasp**,
relative to the object's pose at the episode start, and **the rest** (transport + place, or the
screwing), relative to the target's pose. :data:`TASKS` says per task which frames and which
switch apply, the one table the generator reads (no copy of the generator per task):

- TileSuction: the tile's centre; the tile's target on the pad. The grasp segment ends at the
  suction switch; the suction's command is sent only where it switches (it latches).
- BlockGrip: the block's centre; the block's target on the pad. The grasp segment runs on past
  the switch to the source's grasp (the fingers close over several steps); commands as recorded.
- Screw: the nut's centre; the nut's tightened centre on the bolt (the bolt plate: both frames
  move with it). The grasp segment ends at the source's grasp; the gripper's command and the
  spin (``a[7]``) as recorded.
- TilePlace: TileSuction's frames and switch, each turned with its yaw (``square``): the head
  was set square onto the tile and the tile square onto its pad, modulo 90°, so the grasp
  segment turns with the tile and the rest with the pad (the yaws modulo 90° are in the
  observation: ``cos 4ψ, sin 4ψ`` of each). A source that placed its tile square to its pad
  places it square to the new pad, with the same grasp on the tile.

Each segment is the sequence of tool0 (flange) poses the arm reached, one per recorded action:
the pose after action ``k`` is forward kinematics of the joints in observation ``k + 1`` (the
last action's, of the joints the arm was commanded to, the observation after the end not being
recorded).

For a new start, :func:`transform_poses` moves every pose of a segment rigidly with its frame:
``T_new · T_src⁻¹ · P``. Frames are ``(x, y, z, yaw)`` about Base Z. By default the generator
keeps the source's yaw (``rotate=False``): tile-sim's pick and install are judged on the object's
centre alone, and its yaw is not in the observation, so turning the tool with the object would
make the recorded actions depend on something the policy cannot see. TilePlace judges the yaw
and observes it: its frames always turn (``TaskFrames.square``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import _native, kin, tasks
from mimicrete._native import MimicreteError
from mimicrete.demonstrator.scene import obs_layout


class DemoGenError(MimicreteError, ValueError):
    """A source demo that cannot be segmented, or bad generation input (names the problem)."""


TASK = "TileSuction"  # the default task (the first demogen knew)


@dataclass(frozen=True)
class TaskFrames:
    """What demogen needs of one task (a row of :data:`TASKS`).

    ``lay``: the observation frame's fields (``q``, ``ee``: the effector state, ``tcp``,
    ``target``, ``object``); ``switch``: the action column whose first value ``≥ 0.5`` is the
    effector switch; ``grasp_in_object``: the steps after the switch up to the source's grasp
    (its pick reward) belong to the object-relative segment (a gripper closes over several
    steps at the object); ``latched``: the effector holds its state, so its command is sent only
    when it switches (the suction; as teleop-core records it); ``finish``: what follows the last
    segment when the episode has not ended: ``carry`` the held object the rest of the way onto
    the target, ``hold`` the last pose and command (the spin), or ``none``; ``close_in_reach``:
    the gripper's command in the object-relative segment is "close" from the first step whose
    state lies within the simulator's grasp tolerance (:data:`SCREW_GRASP_TOL`), whatever the
    source commanded there (Screw: the scripted person holds the fingers open at the nut for
    tens of steps before closing, so most states at the nut were labelled "open" and a cloned
    policy's argmax never closed, docs/wide_starts.md); ``screw_from_grasp``: once the object is
    gripped the object-relative segment ends there and the target-relative one (the screwing)
    turns the nut from its first step on (the source held the nut still for some steps before it
    spun it: with the grasp made earlier, a cloned policy held it, drifted 1 cm and slipped off);
    ``action_noise``: the default standard deviation of the noise added to the played joint
    actions (:func:`.generator.generate_episode`; 0: none); ``square``: the object and the
    target are square things whose yaws (modulo 90°) the task judges and observes
    (``lay["object_yaw"]``, ``lay["target_yaw"]``: ``cos 4ψ, sin 4ψ``): both frames turn with
    them (:func:`frame_yaws`); ``follow_object``: the held object may slip across the effector
    (TilePlace's cups hold it by friction), so the target-relative segment steers the object,
    not the TCP, along the source's path (:func:`.generator.generate_episode`)."""

    sim: str
    frame_dim: int
    act_dim: int
    lay: dict[str, slice]
    switch: int
    grasp_in_object: bool
    latched: bool
    finish: str
    close_in_reach: bool = False
    screw_from_grasp: bool = False
    action_noise: float = 0.0
    square: bool = False
    follow_object: bool = False

    @property
    def commands(self) -> slice:
        """The action's effector columns (``a[6]``, and Screw's spin ``a[7]``)."""
        return slice(6, self.act_dim)


def _lay(task: str) -> dict[str, slice]:
    lay = dict(obs_layout(task))
    lay["ee"] = slice(6, 7)  # suction state (+1 on / −1 off) or the finger gap
    if task == "place":  # tile-sim Task::obs_frame_dim: cos 4ψ, sin 4ψ of the tile, the target
        lay["object_yaw"], lay["target_yaw"] = slice(24, 26), slice(26, 28)
    return lay


TASKS: dict[str, TaskFrames] = {
    "TileSuction": TaskFrames("TileSuction", 16, 7, _lay("suction"), 6, False, True, "carry"),
    "BlockGrip": TaskFrames("BlockGrip", 16, 7, _lay("grip"), 6, True, False, "none"),
    "Screw": TaskFrames("Screw", 18, 8, _lay("screw"), 6, True, False, "hold", True, True),
    # placed is judged resting after the source's release: the last pose is held until it rests
    "TilePlace": TaskFrames(
        "TilePlace", 32, 7, _lay("place"), 6, False, True, "hold", square=True, follow_object=True
    ),
}

#: Screw's grasp tolerance, tile-sim's ``nut_contact`` (crates/tile-sim/src/task/screw.rs): the
#: nut's centre in the TCP frame within ``xy`` (m, ``CENTRE_TOL``) across and along the fingers
#: and within ``z`` (m) of the TCP along the tool axis (the fingers' half length 0.025 minus the
#: nut's half height 0.005, ``tasks/screw.toml``), with the flange within ``align_cos`` of
#: pointing down (the spec's ``thresholds.align_cos``)
SCREW_GRASP_TOL = {"xy": 0.006, "z": 0.02, "align_cos": 0.94}


def task_frames(task: str) -> TaskFrames:
    """The :data:`TASKS` row of ``task`` (any spelling :func:`mimicrete.tasks.get` takes); a
    task of the table that has none (the row: demogen is not built for it yet) is a
    :class:`mimicrete.tasks.NotBuiltError`."""
    try:
        sim = tasks.get(task).sim
    except ValueError as e:
        raise DemoGenError(str(e)) from None
    if sim not in TASKS:
        raise tasks.not_built("demogen", task, list(TASKS))
    return TASKS[sim]


def frame_yaws(spec: TaskFrames, f: np.ndarray) -> tuple[float, float]:
    """The object's and the target's yaws (rad, modulo 90°: in ``(-45°, 45°]``) in observation
    frame ``f`` of a ``square`` task, read from their ``cos 4ψ, sin 4ψ``; ``(0, 0)`` for the
    other tasks (their frames do not turn)."""
    if not spec.square:
        return 0.0, 0.0
    o, t = f[spec.lay["object_yaw"]], f[spec.lay["target_yaw"]]
    return float(np.arctan2(o[1], o[0])) / 4.0, float(np.arctan2(t[1], t[0])) / 4.0


def frame(x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
    """A ``(4, 4)`` frame at ``(x, y, z)`` turned by ``yaw`` (rad) about Base Z."""
    c, s = np.cos(yaw), np.sin(yaw)
    f = np.eye(4)
    f[:2, :2] = [[c, -s], [s, c]]
    f[:3, 3] = [x, y, z]
    return f


def transform_poses(poses: np.ndarray, src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Poses ``(n, 4, 4)`` expressed in frame ``src`` carried to the same relative place in
    ``dst``: ``dst · src⁻¹ · P``."""
    rel = dst @ np.linalg.inv(src)
    return np.einsum("ij,njk->nik", rel, np.asarray(poses, dtype=np.float64))


@dataclass
class Segment:
    """One object-centric subtask of a source demo.

    ``poses`` (n, 4, 4): tool0 after each of its actions; ``commands`` (n, c): the recorded
    end-effector command of each (``a[6:]``: one column, Screw two: the gripper and the spin);
    ``relative_to``: ``"object"`` or ``"target"``; ``src``: the frame it was recorded in (4, 4);
    ``object_offsets`` (n, 3): the object's centre minus the TCP after each action (Base)."""

    poses: np.ndarray
    commands: np.ndarray
    relative_to: str
    src: np.ndarray
    object_offsets: np.ndarray

    def __len__(self) -> int:
        return len(self.poses)

    def moved_to(self, dst: np.ndarray) -> np.ndarray:
        """This segment's poses in frame ``dst`` (:func:`transform_poses`)."""
        return transform_poses(self.poses, self.src, dst)

    def object_offsets_in(self, dst: np.ndarray) -> np.ndarray:
        """:attr:`object_offsets` turned as the segment is carried to frame ``dst``."""
        rel = dst[:3, :3] @ self.src[:3, :3].T
        return self.object_offsets @ rel.T


@dataclass
class SourceDemo:
    """A recorded demo split into its two segments."""

    name: str
    object: np.ndarray  # (3,) the object's centre at the start (tile, block, nut)
    target: np.ndarray  # (3,) the target at the start
    segments: list[Segment] = field(default_factory=list)
    meta: dict[str, str] = field(default_factory=dict)
    task: str = TASK  # tile-sim's name
    #: the object's and the target's yaws its segments' frames turn with (rad; 0 but for a
    #: ``square`` task: :func:`frame_yaws`)
    yaws: tuple[float, float] = (0.0, 0.0)

    @property
    def task_file(self) -> str | None:
        """The task spec file the demo was recorded in (its ``task_file`` metadata; None: the
        built-in task)."""
        return self.meta.get("task_file")

    @property
    def robot(self) -> str:
        """The arm the demo ran on (its ``robot_model`` metadata; ``ur3`` for demos without it):
        the kinematics its poses were computed with and the new episodes are played with."""
        return self.meta.get("robot_model") or "ur3"

    @property
    def length(self) -> int:
        return sum(len(s) for s in self.segments)

    @property
    def spec(self) -> TaskFrames:
        return TASKS[self.task]


def segment_episode(
    obs: np.ndarray,
    actions: np.ndarray,
    name: str = "demo",
    meta: dict[str, str] | None = None,
    *,
    task: str = TASK,
    rewards: np.ndarray | None = None,
) -> SourceDemo:
    """Split one recorded episode of ``task`` (obs ``(T, 5·frame)``, actions ``(T, act_dim)``,
    ``rewards (T,)``: needed where the grasp ends after the switch) at its effector switch."""
    spec = task_frames(task)
    obs, actions = np.asarray(obs), np.asarray(actions)
    want_obs, want_act = 5 * spec.frame_dim, spec.act_dim
    if obs.ndim != 2 or obs.shape[1] != want_obs or actions.shape != (len(obs), want_act):
        raise DemoGenError(
            f"{name}: not a {spec.sim} demo (obs {obs.shape}, actions "
            f"{actions.shape}; expected (T, {want_obs}) and (T, {want_act}))"
        )
    f = np.asarray(obs, np.float64)[:, -spec.frame_dim :]
    on = np.flatnonzero(actions[:, spec.switch] >= 0.5)
    what = "the suction is never switched on" if spec.latched else "the gripper never closes"
    if len(on) == 0:
        raise DemoGenError(f"{name}: {what}; nothing to segment")
    k = int(on[0])
    if spec.grasp_in_object:  # the grasp ends at the source's pick (its +1), after the switch
        if rewards is None or len(rewards) != len(obs):
            raise DemoGenError(f"{name}: no per-step rewards to find the grasp in")
        picks = np.flatnonzero(np.asarray(rewards)[k:] >= 0.5)
        if len(picks) == 0:
            raise DemoGenError(f"{name}: the gripper closes at step {k} but never grasps")
        k += int(picks[0]) + 1
    if k < 2 or k > len(obs) - 3:
        raise DemoGenError(
            f"{name}: the grasp segment ends at step {k} of {len(obs)}; a segment would be empty"
        )
    lay = spec.lay
    # the joints after each action: the next frame's; after the last one, the simulator's step
    last = _native.joint_motion(spec_of(meta, spec.sim), f[-1, lay["q"]], actions[-1])
    q_after = np.vstack([f[1:, lay["q"]], last[None]])
    poses = kin.fk_batch(q_after, model=(meta or {}).get("robot_model") or "ur3")
    # the object's offset from the TCP after each action (the last one's: as after the one before)
    after = np.vstack([f[1:], f[-1:]])
    offsets = after[:, lay["object"]] - after[:, lay["tcp"]]
    obj, target = f[0, lay["object"]], f[0, lay["target"]]
    yaws = frame_yaws(spec, f[0])
    cmds = actions[:, spec.commands].astype(np.float64)
    segs = [
        Segment(poses[:k], cmds[:k], "object", frame(*obj, yaws[0]), offsets[:k]),
        Segment(poses[k:], cmds[k:], "target", frame(*target, yaws[1]), offsets[k:]),
    ]
    return SourceDemo(name, obj.copy(), target.copy(), segs, dict(meta or {}), spec.sim, yaws)


def spec_of(meta: dict[str, str] | None, sim: str) -> dict[str, Any]:
    """The task spec (a dict) of the env a demo ran in: its ``task_spec`` metadata (a demo
    recorded in a spec file), else the built-in spec of its simulator task ``sim``."""
    import json

    text = (meta or {}).get("task_spec")
    return json.loads(text) if text else _native.task_spec(sim)


def load_sources(path: str | Path, count: int | None = None) -> list[SourceDemo]:
    """The first ``count`` (all: None) MCAP demos of a file or directory, segmented. The task
    is the demos' own (their ``task`` metadata; one task per call). Only successful demos are
    used (a failed one is no source)."""
    path = Path(path)
    if not path.exists():
        raise DemoGenError(f"--demos {path}: no such file or directory")
    files = [Path(p) for p in _native.demo_files(str(path))]
    if not files:
        raise DemoGenError(f"--demos {path}: no *.mcap demos in it")
    out: list[SourceDemo] = []
    for p in files:
        if count is not None and len(out) >= count:
            break
        d: Any = _native.demo_read(str(p))
        meta = dict(d["meta"])
        task = task_frames(meta.get("task", TASK)).sim
        if out and task != out[0].task:
            raise DemoGenError(
                f"--demos {path}: mixes tasks ({out[0].name} is a {out[0].task} demo, "
                f"{p.name} a {task} demo); generate from one task's demos at a time"
            )
        if out and meta.get("task_spec") != out[0].meta.get("task_spec"):
            raise DemoGenError(
                f"--demos {path}: mixes task specs ({out[0].name} was recorded in "
                f"{out[0].task_file or 'the built-in spec'}, {p.name} in "
                f"{meta.get('task_file') or 'the built-in spec'}); generate from one spec's demos"
            )
        if meta.get("success") == "false":
            continue
        out.append(
            segment_episode(
                d["obs"], d["actions"], p.name, meta, task=task, rewards=d.get("rewards")
            )
        )
    if not out:
        raise DemoGenError(f"--demos {path}: no successful demo to generate from")
    _check_spec_file(out[0])
    return out


def _check_spec_file(src: SourceDemo) -> None:
    """A source recorded in a task spec file: the file must still hold that spec (the demos are
    generated in it)."""
    import json

    path = src.task_file
    if path is None:
        return
    try:
        _, spec = tasks.load_task_file(path)
    except (OSError, ValueError) as e:
        raise DemoGenError(f"{src.name}: task file {tasks.task_file_error(path, e)}") from None
    if json.loads(json.dumps(spec, sort_keys=True)) != json.loads(src.meta["task_spec"]):
        raise DemoGenError(
            f"{src.name}: task file {path} is not the spec the demo was recorded in (it changed "
            "since)"
        )


def retime(n: int, speed: float) -> np.ndarray:
    """The indices of ``n`` steps played ``speed`` times faster: the last step of each window of
    about ``speed`` steps, counted back from the last step ``n − 1`` (``ceil(n / speed)`` of
    them, every window ``floor(speed)`` or ``ceil(speed)`` long)."""
    if not speed >= 1.0:
        raise DemoGenError(f"speed must be at least 1, got {speed}")
    m = max(1, int(np.ceil(n / speed - 1e-9)))
    back = np.floor(np.arange(m - 1, -1, -1) * speed + 1e-9).astype(int)
    return np.maximum(0, n - 1 - back)


def window_commands(commands: np.ndarray, keep: np.ndarray, latched: bool) -> np.ndarray:
    """The effector commands of the steps :func:`retime` keeps: a level's (the gripper, the
    spin) is its window's last; a latched switch (the suction's, sent on one step) is the
    window's last non-zero one, so no switch is skipped."""
    out = np.array(commands[keep], np.float64, copy=True)
    if latched:
        lo = 0
        for j, hi in enumerate(keep):
            on = np.flatnonzero(np.any(commands[lo : hi + 1] != 0.0, axis=1))
            out[j] = commands[lo + on[-1]] if len(on) else 0.0
            lo = hi + 1
    return out
