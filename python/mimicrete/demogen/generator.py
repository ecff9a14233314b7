"""Generate demos at new starts from a few source demos (MimicGen's loop) in the real simulator.

For each attempt: draw a start (tile-sim's wide or training starts, or a starts file), reset the
simulator there explicitly (``object_pose``, ``target_offset``, a turned pad's ``pad_yaw``), pick
a source demo, carry each of its segments into the new tile / target frame (:mod:`.segment`),
connect it to where the arm is by blending the offset out over the segment's first part (a
min-jerk interpolation from the current pose onto the transformed path; the tool's turn about
Base Z too where the frames turn, TilePlace), and follow the poses with the project's IK, producing
the actions a teleoperated demo records (the simulator's ``SimEnv.action_toward`` of the IK's
answer, warm-started at its last one: ``clip(wrap(q_ik − q) / joint_step, −1, 1)`` in the joint
space, the TCP's motion and turn towards the answer's in the tool space of a spec with
``robot.action = "tool"``, TilePlace). The
effector commands are the source's (the suction's only at its switch, once the cup is within
reach of the grasp point; the gripper's and the spin as recorded, the gripper kept closing until
it holds; Screw's gripper "close" from the first step within the grasp tolerance of the nut on,
``TaskFrames.close_in_reach``). What differs per task is one row of :data:`.segment.TASKS`.
Only episodes that succeed (install, place, screw) are kept (MimicGen keeps successes); each is
written as an MCAP demo with the project's writer, its metadata saying it was generated, from
which source and where it started (``mimicrete train --demos DIR`` reads it unchanged).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import IkError, MimicreteError, _native, kin, tasks
from mimicrete.demonstrator.scene import square_turn

from .segment import (
    SCREW_GRASP_TOL,
    TASK,
    DemoGenError,
    SourceDemo,
    TaskFrames,
    frame,
    frame_yaws,
    retime,
    task_frames,
    window_commands,
)

CONTROL_DT = tasks.CONTROL_DT
MAX_STEPS = tasks.MAX_EPISODE_STEPS
PICK_REACH = 0.03  # m: switch the suction on only with the cup this close to the grasp point
#: rad: an IK answer further than this from the last one is another branch (teleop-core's limit)
BRANCH_JUMP = float(_native.TELEOP_BRANCH_JUMP)


def min_jerk(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s)


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def sim_env(task: str, task_file: str | None = None) -> Any:
    """A ``SimEnv`` of ``task``, or of the task spec file ``task_file`` if given."""
    if task_file is not None:
        return _native.SimEnv.from_spec_file(task_file, 0)
    return _native.SimEnv(task_frames(task).sim, 0)


def robot_model(sim: Any) -> str:
    """The arm ``sim`` (a ``SimEnv``) simulates: its spec's ``robot.model`` (``ur3`` …)."""
    return str(sim.spec()["robot"]["model"])


def draw_starts(
    n: int, seed: int, starts: str = "wide", task: str = TASK, task_file: str | None = None
) -> list[dict[str, list[float]]]:
    """``n`` starts of ``task``'s tile-sim ``starts`` distribution (``wide``, ``training``,
    ``robust``; the spec file ``task_file``'s if given), drawn by the simulator itself from
    episode seeds of ``seed``: ``object_pose``, ``target_offset``, and ``pad_yaw`` (rad) where
    the start turns the pad (TilePlace's wide starts)."""
    sim = sim_env(task, task_file)
    if starts == "robust":
        sim.set_variation(robust=True)
    else:
        sim.set_variation(starts=starts)
    rng = np.random.default_rng([seed, 0xDE70])
    out = []
    for s in rng.integers(0, 2**62, size=n):
        sim.reset(int(s))
        st = sim.start()
        start = {
            "object_pose": [float(v) for v in st["object_pose"]],
            "target_offset": [float(v) for v in st["target_offset"]],
        }
        if st.get("pad_yaw"):
            start["pad_yaw"] = float(st["pad_yaw"])
        out.append(start)
    return out


@dataclass
class GeneratedEpisode:
    """One generated episode: what a demo records per step, and how it went."""

    source: str
    start: dict[str, list[float]]
    seed: int
    rows: list[dict[str, Any]] = field(default_factory=list)
    installed: bool = False
    picked: bool = False
    why: str = ""
    task: str = TASK

    @property
    def steps(self) -> int:
        return len(self.rows)


def _pose7(p: dict[str, Any]) -> list[float]:
    return [*map(float, p["t"]), *map(float, p["q"])]


def gesture_of(spec: TaskFrames, cmd: np.ndarray, on: bool) -> str:
    """The gesture class a demo step records for effector command ``cmd`` (``a[6:]``), as the
    teleoperation session records it (``on``: the suction is on before the step)."""
    c = float(cmd[0])
    if spec.latched:
        return "closing" if (on or c >= 0.5) else "opening"
    name = "closing" if c >= 0.5 else ("opening" if c <= -0.5 else "fixed")
    if spec.act_dim == 8:  # the screwing classes (the gripper, the spin)
        spin = float(cmd[1])
        tail = "tightening" if spin >= 0.5 else ("loosening" if spin <= -0.5 else "fixed")
        return {"closing": f"closing_{tail}", "opening": "opening_stopped"}.get(
            name, "fixed_stopped"
        )
    return name


class _Runner:
    """Steps the simulator towards tool0 poses and records every step."""

    def __init__(
        self,
        sim: Any,
        ep: GeneratedEpisode,
        obs: np.ndarray,
        spec: TaskFrames | None = None,
        action_noise: float = 0.0,
    ) -> None:
        self.sim, self.ep, self.obs = sim, ep, obs
        self.spec = spec or task_frames(ep.task)
        self.noise = float(action_noise)
        self.rng = np.random.default_rng([ep.seed, 0xA7])
        snap = sim.snapshot()
        self.q = np.asarray(snap["q"], np.float64)
        self.q_ik = self.q.copy()
        self.model = robot_model(sim)
        self.done = False

    def pose(self) -> np.ndarray:
        return kin.fk(self.q, model=self.model)

    def held(self) -> bool:
        return bool(self.sim.snapshot()["held"])

    def step(self, target: np.ndarray, command: float | np.ndarray) -> None:
        spec = self.spec
        try:
            sol = kin.ik(target, seed=self.q_ik, model=self.model)
        except IkError:
            raise _Abort("unreachable pose") from None
        if np.max(np.abs(wrap(sol - self.q_ik))) > BRANCH_JUMP:
            raise _Abort("IK jumped to another branch")
        self.q_ik = sol
        cmd = np.zeros(spec.act_dim - 6, np.float64)
        cmd[:] = np.atleast_1d(np.asarray(command, np.float64))[: len(cmd)]
        a = np.zeros(spec.act_dim, np.float32)
        a[:6] = self.sim.action_toward(self.q_ik)
        if self.noise > 0:  # MimicGen's action noise: executed and recorded (see generate)
            a[:6] = np.clip(a[:6] + self.noise * self.rng.standard_normal(6), -1.0, 1.0)
        a[6:] = cmd
        frame_now = self.obs[-spec.frame_dim :]
        on = bool(frame_now[spec.lay["ee"]][0] > 0.0) if spec.latched else False
        if spec.latched and ((cmd[0] >= 0.5 and on) or (cmd[0] <= -0.5 and not on)):
            a[6] = 0.0  # the suction latches: a command only where it switches
        obs_before = self.obs
        obs, r, term, trunc, info = self.sim.step(a)
        snap = self.sim.snapshot()
        self.q = np.asarray(snap["q"], np.float64)
        events = []
        if info["picked"] and not self.ep.picked:
            events.append("pick")
        if info["installed"]:
            events.append("install")
        if info["fell"]:
            events.append("fall")
        self.ep.picked |= bool(info["picked"])
        self.ep.installed |= bool(info["installed"])
        self.ep.rows.append(
            {
                "obs": np.asarray(obs_before, np.float32),
                "action": a,
                "reward": float(r),
                "terminated": bool(term),
                "truncated": bool(trunc),
                "gesture": gesture_of(spec, a[6:], on),
                "joints": self.q.tolist(),
                "ee_pose": _pose7(snap["tool0"]),
                "tile_pose": _pose7(snap["object"]),
                "events": events,
            }
        )
        self.obs = obs
        if term or trunc:
            self.done = True
            raise _Abort("fell" if info["fell"] else ("installed" if info["installed"] else "time"))


class _Abort(MimicreteError):
    """A generated episode given up (unreachable, an IK branch jump, the task ended early):
    counted in the report, never raised to a caller."""


def _blended(poses: np.ndarray, start: np.ndarray, share: float, turn: bool = False) -> np.ndarray:
    """``poses`` with the offset of their first position from ``start`` (4, 4) blended out over
    the first ``share`` of them (min-jerk): the path leaves from where the arm is and joins the
    transformed segment. ``turn``: the offset of the tool's turn about Base Z too (the frames of
    a ``square`` task turn, so consecutive segments meet at different turns; each pose turns
    about its own origin, the flange, above the TCP of a tool pointing down)."""
    out = poses.copy()
    n = max(2, int(round(share * len(poses))))
    w = min_jerk(np.arange(1, len(poses) + 1) / n)
    offset = start[:3, 3] - poses[0, :3, 3]
    out[:, :3, 3] += (1.0 - w)[:, None] * offset
    if turn:
        yaw = wrap(_yaw(start) - _yaw(poses[0]))
        out[:, :3, :3] = _rot_z((1.0 - w) * yaw) @ out[:, :3, :3]
    return out


def _yaw(pose: np.ndarray) -> float:
    """The turn about Base Z of a pose's x axis (rad)."""
    return float(np.arctan2(pose[1, 0], pose[0, 0]))


def _rot_z(angles: np.ndarray) -> np.ndarray:
    """Rotations ``(n, 3, 3)`` about Base Z by ``angles`` (rad)."""
    c, s = np.cos(angles), np.sin(angles)
    r = np.zeros((len(angles), 3, 3))
    r[:, 0, 0], r[:, 0, 1], r[:, 1, 0], r[:, 1, 1], r[:, 2, 2] = c, -s, s, c, 1.0
    return r


def generate_episode(
    sim: Any,
    src: SourceDemo,
    start: dict[str, list[float]],
    seed: int = 0,
    *,
    blend: float = 0.5,
    rotate: bool = False,
    grasp_jitter: float = 0.0,
    action_noise: float | None = None,
    speed: float = 1.0,
) -> GeneratedEpisode:
    """Run one generated episode of ``src`` at ``start`` in ``sim`` (a ``SimEnv`` of the
    source's task).

    ``grasp_jitter`` (m, 0: off): the object-relative segment is shifted along the tool's x axis
    (the gripper fingers' faces, where closing does not centre the object) by a uniform draw in
    ``[-grasp_jitter, grasp_jitter]`` (from ``seed``), so the object is grasped off-centre as a
    policy grasps it; once held, the target-relative segment is shifted by minus the object's
    horizontal offset from the TCP, so the object, not the TCP, arrives where the source put it.
    Without it every generated grasp is centred (BlockGrip: the block within 2 mm of the TCP at
    the place), and neither BC nor a reverse curriculum over the demos shows a place that
    corrects for an off-centre block.

    A task whose held object may slip across the effector (``follow_object``: TilePlace) steers
    the object, not the TCP, along the source's path in the target-relative segment: while it is
    held, each pose is moved sideways by the object's offset from the TCP in the source at that
    step minus its offset now, so a tile that slid in the cups still lands where the source's
    landed (MimicGen transforms the object's path; with a rigid grasp that is the effector's).

    ``action_noise`` (None: the task's :attr:`.segment.TaskFrames.action_noise`): the standard
    deviation of Gaussian noise added to every joint action (units of the env's joint step, clipped
    to ``[-1, 1]``; from ``seed``), as MimicGen adds it to the actions it plays (its
    ``action_noise``, 0.05 in its configs). The noisy action is the one executed and recorded (so
    a curriculum's replay reaches the recorded states); the IK keeps tracking the clean path, so
    the next action corrects the deviation, and the demos show the way back to the path from
    states beside it (DART, Laskey et al. 2017), which noise-free demos never visit.

    ``speed`` (≥ 1): each segment is played ``speed`` times faster (:func:`.segment.retime`): a
    person's demo hovers and creeps where a robot need not, and every step it takes is a step the
    learner must credit a sparse reward across. The simulator still clips each step to the arm's
    limits (``joint_step``, ``tool_step``), so a fast stretch is followed a few steps late, and
    an episode that no longer succeeds is not kept."""
    spec = src.spec
    noise = spec.action_noise if action_noise is None else float(action_noise)
    ep = GeneratedEpisode(src.name, start, int(seed), task=spec.sim)
    obs = sim.reset(
        int(seed),
        object_pose=start["object_pose"],
        target_offset=start.get("target_offset", [0.0, 0.0]),
        pad_yaw=start.get("pad_yaw"),
    )
    f = np.asarray(obs, np.float64)[-spec.frame_dim :]
    yaw = float(start["object_pose"][2]) if rotate else 0.0
    target_yaw = 0.0
    if spec.square:  # turned by the least turn that squares the source's frames to the new ones
        (src_o, src_t), (new_o, new_t) = src.yaws, frame_yaws(spec, f)
        yaw, target_yaw = src_o + square_turn(src_o, new_o), src_t + square_turn(src_t, new_t)
    frames = {
        "object": frame(*f[spec.lay["object"]], yaw),
        "target": frame(*f[spec.lay["target"]], target_yaw),
    }
    run = _Runner(sim, ep, np.asarray(obs, np.float32), spec, noise)
    last = run.pose()
    shift = float(np.random.default_rng([int(seed), 0x617]).uniform(-1, 1)) * grasp_jitter
    try:
        for seg in src.segments:
            moved = seg.moved_to(frames[seg.relative_to])
            if seg.relative_to == "target":
                _await_grasp(run, spec, last, src.segments[0].commands[-1])
                if grasp_jitter > 0:
                    moved[:, :2, 3] -= _in_hand_offset(run)
            elif grasp_jitter > 0:
                x = moved[-1, :3, 0] * [1.0, 1.0, 0.0]
                moved[:, :3, 3] += shift * x / max(float(np.linalg.norm(x)), 1e-9)
            poses = _blended(moved, run.pose(), blend, turn=spec.square)
            relabel = spec.close_in_reach and seg.relative_to == "object"
            early = spec.screw_from_grasp and seg.relative_to == "object"
            commands = seg.commands
            if spec.screw_from_grasp and seg.relative_to == "target":
                commands = _spin_from_start(commands)
            follow = spec.follow_object and seg.relative_to == "target"
            offsets = seg.object_offsets_in(frames[seg.relative_to]) if follow else None
            if speed != 1.0:
                keep = retime(len(poses), speed)
                poses, commands = poses[keep], window_commands(commands, keep, spec.latched)
                offsets = None if offsets is None else offsets[keep]
            steer = np.zeros(2)  # how far the TCP is moved so the object keeps the source's path
            closing = False
            for k, (p, c) in enumerate(zip(poses, commands, strict=True)):
                if relabel and (closing or _in_grasp_reach(run)):
                    closing = True  # "close" from the first step at the nut on
                    c = c.copy()
                    c[0] = 1.0
                if offsets is not None:
                    if run.held():  # the object slipped by this much since the source's step
                        steer = offsets[k, :2] - _in_hand_offset(run)
                    p = p.copy()
                    p[:2, 3] += steer  # kept after the release: the head leaves straight up
                run.step(p, c)
                last = p
                if early and run.held():
                    break  # gripped: the screwing starts here, not where the source's did
        _finish(run, spec, last, src.segments[-1].commands[-1])
        ep.why = "not installed"
    except _Abort as e:
        ep.why = str(e)
    return ep


def _spin_from_start(commands: np.ndarray) -> np.ndarray:
    """``commands`` (n, 2: the gripper, the spin) with the spin's first command (tighten) from
    the segment's first step on: the source's steps that hold the nut without turning it go."""
    out = np.array(commands, np.float64, copy=True)
    on = np.flatnonzero(out[:, 1] != 0.0)
    if len(on):
        out[: on[0], 1] = out[on[0], 1]
    return out


def _in_grasp_reach(run: _Runner) -> bool:
    """Whether the nut lies within the simulator's grasp tolerance of the fingers now
    (:data:`.segment.SCREW_GRASP_TOL`: its centre in the TCP frame, the flange pointing down)."""
    snap = run.sim.snapshot()
    rot = kin.quat_matrix(snap["tcp"]["q"])
    p = rot.T @ (np.asarray(snap["object"]["t"], np.float64) - np.asarray(snap["tcp"]["t"]))
    tol = SCREW_GRASP_TOL
    aligned = float(-rot[2, 2]) > tol["align_cos"]  # the tool's z against Base −Z
    return bool(
        aligned and abs(p[0]) < tol["xy"] and abs(p[1]) < tol["xy"] and abs(p[2]) < tol["z"]
    )


def _in_hand_offset(run: _Runner) -> np.ndarray:
    """The held object's horizontal offset from the TCP (m, Base frame)."""
    snap = run.sim.snapshot()
    return (np.asarray(snap["object"]["t"]) - np.asarray(snap["tcp"]["t"]))[:2]


def _await_grasp(run: _Runner, spec: TaskFrames, last: np.ndarray, cmd: np.ndarray) -> None:
    """Before the target-relative segment: the suction waits (its command comes with the
    segment) until the cup is within reach of the tile's grasp point; a gripper keeps closing
    at the last pose until it holds (the fingers may touch a step later than the source's)."""
    for _ in range(25):
        if spec.latched:
            snap = run.sim.snapshot()
            grasp = np.asarray(snap["object"]["t"]) + [0.0, 0.0, 0.005]
            if np.linalg.norm(np.asarray(snap["tcp"]["t"]) - grasp) < PICK_REACH:
                return
            run.step(last, 0.0)
        else:
            if run.held():
                return
            run.step(last, cmd)


def _finish(run: _Runner, spec: TaskFrames, last: np.ndarray, cmd: np.ndarray) -> None:
    """After the last segment, where the task has not ended: ``carry`` the held object onto
    the target (≤ 5 mm a step; a source that installed at its very last step would otherwise
    miss by a millimetre), or ``hold`` the last pose and command (the nut keeps turning)."""
    if spec.finish == "none":
        return
    for _ in range(40):
        if spec.finish == "carry":
            snap = run.sim.snapshot()
            gap = np.asarray(snap["target"]["t"]) - np.asarray(snap["object"]["t"])
            n = float(np.linalg.norm(gap))
            last = last.copy()
            last[:3, 3] += gap * min(1.0, 0.005 / max(n, 1e-9))
            run.step(last, 0.0)
        else:
            run.step(last, cmd)


def write_episode(
    ep: GeneratedEpisode,
    path: Path,
    index: int,
    extra: dict[str, Any] | None = None,
    env: Any = None,
) -> Path:
    """Write a generated episode as an MCAP demo (the project's demo-log writer); ``env``: the
    ``SimEnv`` it ran in, whose scene at the episode's start (the pad where the start moved it)
    the demo draws (None: the task's at the seed's paper start)."""
    from mimicrete import demos

    info = {
        "generated": "true",
        "generator": "mimicrete demogen (object-centric segments, MimicGen)",
        "source_demo": ep.source,
        "start": json.dumps(ep.start),
        "object_pose": json.dumps(ep.start["object_pose"]),
        "target_offset": json.dumps(ep.start.get("target_offset", [0.0, 0.0])),
        **({"pad_yaw": json.dumps(ep.start["pad_yaw"])} if "pad_yaw" in ep.start else {}),
        **{k: (v if isinstance(v, str) else json.dumps(v)) for k, v in (extra or {}).items()},
    }
    meta = {
        "episode": int(index),
        "task": ep.task,
        "seed": int(ep.seed),
        "robot_model": "ur3" if env is None else robot_model(env),
        "gesture_model": "",
        "control_dt": CONTROL_DT,
        "extra": info,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    w = demos.DemoWriter(str(path), meta, env=env)
    try:
        for k, r in enumerate(ep.rows):
            w.write_step(
                k,
                k * CONTROL_DT,
                r["obs"],
                r["action"],
                r["reward"],
                r["terminated"],
                r["truncated"],
                r["gesture"],
                r["joints"],
                r["ee_pose"],
                r["tile_pose"],
                r["events"] or None,
            )
        w.finish(ep.installed, {"steps": str(ep.steps), "picked": json.dumps(ep.picked)})
    except BaseException:
        w.abandon()
        Path(str(path) + ".partial").unlink(missing_ok=True)
        raise
    return path


@dataclass
class Report:
    """What a generation run did."""

    attempts: int = 0
    kept: int = 0
    seconds: float = 0.0
    failures: dict[str, int] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)

    @property
    def yield_(self) -> float:
        return self.kept / self.attempts if self.attempts else 0.0


def generate(
    sources: list[SourceDemo],
    count: int,
    out: str | Path,
    *,
    starts: str | Iterable[dict[str, list[float]]] = "wide",
    seed: int = 0,
    max_attempts: int | None = None,
    progress: Callable[[Report], None] | None = None,
    rotate: bool = False,
    grasp_jitter: float = 0.0,
    action_noise: float | None = None,
    speed: float = 1.0,
) -> Report:
    """Generate until ``count`` installing demos are written into ``out`` (or ``max_attempts``,
    default ``4 · count + 20``, are used up). ``starts``: a named distribution (drawn with
    ``seed``) or explicit starts, used in order and cycled. ``grasp_jitter``: off-centre grasps
    with the place corrected for them; ``action_noise``: noise on the played joint actions (None:
    the task's default) (:func:`generate_episode`)."""
    if not sources:
        raise DemoGenError("no source demo")
    task, task_file = sources[0].task, sources[0].task_file
    if any(s.task != task for s in sources):
        raise DemoGenError("the source demos mix tasks; generate from one task's at a time")
    if any(s.meta.get("task_spec") != sources[0].meta.get("task_spec") for s in sources):
        raise DemoGenError("the source demos mix task specs; generate from one spec's at a time")
    if count < 1:
        raise DemoGenError(f"--count must be at least 1, got {count}")
    out = Path(out)
    limit = max_attempts if max_attempts is not None else 4 * count + 20
    if isinstance(starts, str):
        pool = draw_starts(limit, seed, starts, task, task_file)
    else:
        pool = list(starts)
        if not pool:
            raise DemoGenError("no start to generate at")
    rng = np.random.default_rng([seed, 0x6E4])
    noise = sources[0].spec.action_noise if action_noise is None else float(action_noise)
    sim = sim_env(task, task_file)
    spec_meta = {} if task_file is None else tasks.task_file_meta(task_file, sim.spec())
    rep = Report()
    t0 = time.monotonic()
    while rep.kept < count and rep.attempts < limit:
        start = pool[rep.attempts % len(pool)]
        src = sources[int(rng.integers(len(sources)))]
        ep_seed = int(rng.integers(0, 2**62))
        try:
            ep = generate_episode(
                sim,
                src,
                start,
                ep_seed,
                rotate=rotate,
                grasp_jitter=grasp_jitter,
                action_noise=action_noise,
                speed=speed,
            )
        except ValueError as e:  # the simulator refused the start (off the table, out of reach)
            raise DemoGenError(f"start {rep.attempts}: {e}") from None
        rep.attempts += 1
        if ep.installed:
            name = out / f"gen_{rep.kept:05d}.mcap"
            extra = {"attempt": rep.attempts - 1, "demogen_seed": seed, **spec_meta}
            if noise > 0:
                extra["action_noise"] = noise
            if speed != 1.0:
                extra["speed"] = speed
            write_episode(ep, name, rep.kept, extra, env=sim)
            rep.files.append(name)
            rep.kept += 1
        else:
            rep.failures[ep.why] = rep.failures.get(ep.why, 0) + 1
        rep.seconds = time.monotonic() - t0
        if progress is not None:
            progress(rep)
    return rep
