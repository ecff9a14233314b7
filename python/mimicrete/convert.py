"""Hand logs → MCAP demonstrations: the teleoperation path of paper §3.2, driven from files.

``mimicrete convert HANDLOG_OR_DIR --task suction --out DIR`` runs every hand log through:

1. parse, once up front, by the project's one hand-log parser (:func:`mimicrete.handlog.parse`,
   Rust ``demo-log``; ``mimicrete.LogFormatError`` with ``file:line: reason`` on bad input);
2. gesture per frame (the task's SVM, :mod:`mimicrete.gestures`) and a hysteresis smoother, so a
   single misread frame never changes the end-effector command;
3. the hand frame: the wrist / index-proximal / middle-proximal joints, low-pass filtered with a
   One Euro filter (tracking jitter on knuckles 2 cm apart would otherwise shake the tool),
   mapped to a tool0 target in the robot Base by ``hand_to_target`` with the log's calibration;
4. inverse kinematics warm-started from the previous solution, unwrapped next to the current
   joints (no 2π jumps);
5. the action the environment accepts: ``clip((q_ik − q) / MAX_JOINT_STEP, −1, 1)`` for the
   joints, the smoothed gesture's command ∈ {−1, 0, +1} (and the spin for screwing); the
   suction, which latches, gets a command only when it switches (:func:`recorded_command`);
6. the simulator steps at its control rate (the 90 Hz tracking stream is resampled: each env
   step uses the newest filtered hand state at its start time);
7. one MCAP demo per episode.

Frames the pipeline cannot use are counted, never turned into made-up motion: untracked frames
and degenerate hands keep the last target; an unreachable target (IK fails) keeps the last
solution. The counts are printed per file and stored in the demo's metadata.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import LogFormatError, MimicreteError, handlog
from mimicrete import gestures as gest
from mimicrete import handmodel as hm
from mimicrete.handlog import HandLogData

#: Hand-log task → simulator task id.
SIM_TASK: dict[str, str] = {"suction": "TileSuction", "grip": "BlockGrip", "screw": "Screw"}
TASK_ALIASES: dict[str, str] = {
    "suction": "suction",
    "tilesuction": "suction",
    "grip": "grip",
    "gripping": "grip",
    "blockgrip": "grip",
    "screw": "screw",
    "screwing": "screw",
}

#: Gesture class → (end-effector command, spin) (tile-sim action a[6], a[7]).
COMMANDS: dict[str, tuple[float, float]] = {
    "closing": (1.0, 0.0),
    "opening": (-1.0, 0.0),
    "fixed": (0.0, 0.0),
    "closing_tightening": (1.0, 1.0),
    "closing_loosening": (1.0, -1.0),
    "closing_fixed": (1.0, 0.0),
    "opening_stopped": (-1.0, 0.0),
    "fixed_stopped": (0.0, 0.0),
}


# ----------------------------------------------------------------------------------------------
# Filtering
# ----------------------------------------------------------------------------------------------


class OneEuro:
    """One Euro filter (Casiez, Roussel & Vogel, CHI 2012) on a vector signal.

    A low-pass filter whose cutoff rises with the signal's speed: strong smoothing when the hand
    is still (jitter), little lag when it moves.
    """

    def __init__(self, min_cutoff: float = 1.0, beta: float = 2.0, d_cutoff: float = 1.0) -> None:
        self.min_cutoff, self.beta, self.d_cutoff = min_cutoff, beta, d_cutoff
        self.x: np.ndarray | None = None
        self.dx: np.ndarray | None = None
        self.t: float | None = None

    @staticmethod
    def _alpha(cutoff: float, dt: float) -> float:
        tau = 1.0 / (2.0 * math.pi * cutoff)
        return 1.0 / (1.0 + tau / dt)

    def reset(self) -> None:
        self.x = self.dx = self.t = None

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if self.x is None or self.t is None or t <= self.t:
            self.x, self.dx, self.t = x.copy(), np.zeros_like(x), t
            return self.x
        dt = t - self.t
        dx = (x - self.x) / dt
        a_d = self._alpha(self.d_cutoff, dt)
        self.dx = a_d * dx + (1.0 - a_d) * self.dx
        cutoff = self.min_cutoff + self.beta * float(np.linalg.norm(self.dx))
        a = self._alpha(cutoff, dt)
        self.x = a * x + (1.0 - a) * self.x
        self.t = t
        return self.x


def wrap_to_pi(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to ``[-π, π)``."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def joint_action(q_ik: np.ndarray, q: np.ndarray, max_step: float) -> np.ndarray:
    """``clip(wrap(q_ik − q) / max_step, −1, 1)``: the shortest way round, at most one full step."""
    return np.clip(wrap_to_pi(np.asarray(q_ik) - np.asarray(q)) / max_step, -1.0, 1.0)


@dataclass
class Counts:
    """What happened to the frames of one log."""

    frames: int = 0
    untracked: int = 0
    degenerate: int = 0
    unreachable: int = 0
    steps: int = 0
    frames_after_end: int = 0
    gesture_changes: int = 0
    gestures: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


# ----------------------------------------------------------------------------------------------
# The pipeline
# ----------------------------------------------------------------------------------------------


def canonical_task(name: str) -> str:
    """``suction`` / ``grip`` / ``screw`` from any accepted spelling."""
    key = name.lower().replace("-", "").replace("_", "")
    if key not in TASK_ALIASES:
        raise ValueError(f"unknown task {name!r}; known: suction, grip, screw")
    return TASK_ALIASES[key]


@dataclass
class FrameResult:
    """What the pipeline made of one hand frame."""

    gesture: str | None  # the smoothed gesture after this frame
    target: np.ndarray | None  # tool0 target (4, 4) in Base, None before the first usable frame


class Teleop:
    """The per-frame part of the pipeline (gesture → smoothing → filtered hand frame → target).

    Args:
        task: ``suction``, ``grip`` or ``screw``.
        layout: joint order of the frames.
        handedness: ``left`` / ``right``.
        calibration: headset space → Base (:class:`mimicrete.kin.Calibration`).
        model: the gesture model (default: the shipped one for the task).
        hand_to_target: ``f(wrist, index_proximal, middle_proximal, handedness, calib) -> (4, 4)``
            (default: ``mimicrete.kin.hand_to_target`` with the calibration converted).
    """

    def __init__(
        self,
        task: str,
        layout: str,
        handedness: str,
        calibration: Any,
        model: gest.GestureModel | None = None,
        hand_to_target: Any = None,
        smoother: gest.GestureSmoother | None = None,
    ) -> None:
        self.task = canonical_task(task)
        self.layout = hm.check_layout(layout)
        self.handedness = handedness
        self.calibration = calibration
        self.model = model or gest.load_default(self.task)
        self.smoother = smoother or gest.GestureSmoother(n=7, k=5)
        self.frame_idx = hm.FRAME_JOINTS[self.layout]
        self.filter = OneEuro(min_cutoff=1.0, beta=2.0)
        self.hand_to_target = hand_to_target or bound_hand_to_target(calibration)
        self.target: np.ndarray | None = None
        self.counts = Counts()

    def push(self, t: float, tracked: bool, joints: np.ndarray) -> FrameResult:
        """Feed one hand frame; returns the current smoothed gesture and target."""
        c = self.counts
        c.frames += 1
        if not tracked:
            c.untracked += 1
            return FrameResult(self.smoother.state, self.target)
        raw = self.model.predict_one(joints, self.handedness, self.layout)
        before = self.smoother.state
        gesture = self.smoother.update(raw)
        if gesture != before and before is not None:
            c.gesture_changes += 1
        if raw is None:
            c.degenerate += 1
            return FrameResult(gesture, self.target)
        c.gestures[raw] = c.gestures.get(raw, 0) + 1
        w, i, m = self.frame_idx
        pts = self.filter(np.concatenate([joints[w], joints[i], joints[m]]), t)
        try:
            target = self.hand_to_target(
                pts[:3], pts[3:6], pts[6:9], self.handedness, self.calibration
            )
        except (ValueError, MimicreteError):  # degenerate hand (collinear frame joints)
            c.degenerate += 1
            return FrameResult(gesture, self.target)
        self.target = np.asarray(target, dtype=np.float64)
        return FrameResult(gesture, self.target)

    def command(self) -> tuple[float, float]:
        """The end-effector command and spin for the current smoothed gesture (0, 0 before any)."""
        g = self.smoother.state
        return COMMANDS[g] if g is not None else (0.0, 0.0)


def recorded_command(task: str, cmd: float, frame: np.ndarray) -> float:
    """The end-effector command a demo step records and the env receives, given the newest
    observation frame. tile-sim's suction latches (on stays on until a drop), so a command that
    repeats the suction's state (``frame[6]``: +1 on, −1 off) is sent as "fixed" (0): the robot
    does exactly the same, and the demo marks the two decisions (switch on, drop) instead of
    labelling every approach step "drop" and every carry step "on". With level labels a policy
    keeps some probability of "drop" in carry states, which look like approach states, and every
    such sample loses the tile. The gripper moves only while commanded, so its commands (and the
    screw's spin) stay as gestured."""
    if task != "suction":
        return cmd
    on = frame[6] > 0
    if (cmd >= 0.5 and on) or (cmd <= -0.5 and not on):
        return 0.0
    return cmd


def bound_hand_to_target(calibration: Any) -> Any:
    """``mc.kin.hand_to_target`` with the calibration converted and checked once, not per frame
    (the per-frame path then only crosses into Rust). Same results as the public function."""
    from mimicrete import _native, kin

    mat, scale, space = kin._calib(calibration)
    native = _native.kin_hand_to_target

    def h2t(wrist, index_proximal, middle_proximal, handedness, _calibration=None):
        return native(wrist, index_proximal, middle_proximal, handedness, mat, scale, space)

    return h2t


# ----------------------------------------------------------------------------------------------
# Episodes
# ----------------------------------------------------------------------------------------------


@dataclass
class EpisodeResult:
    """The outcome of converting one hand log."""

    source: str
    out: str | None
    episode_seed: int
    steps: int
    rewards: list[float]
    actions: np.ndarray
    picked: bool
    installed: bool
    fell: bool
    terminated: bool
    truncated: bool
    counts: Counts


def sim_constants() -> tuple[float, float]:
    """``(CONTROL_DT seconds, MAX_JOINT_STEP radians)`` of the simulator."""
    from mimicrete import _native

    c = _native.sim_constants()
    return float(c["CONTROL_DT"]), float(c["MAX_JOINT_STEP"])


class SimAdapter:
    """``mimicrete._native.SimEnv`` with gymnasium's ``reset``/``step`` shapes (no wrappers, no
    checks beyond the simulator's own: the converter's per-frame budget is a millisecond)."""

    def __init__(self, task: str) -> None:
        from mimicrete import _native

        self.env = _native.SimEnv(SIM_TASK[task])

    def reset(self, seed: int) -> tuple[np.ndarray, dict[str, Any]]:
        return self.env.reset(int(seed)), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        return self.env.step(action)

    def snapshot(self) -> dict[str, Any]:
        return self.env.snapshot()


def calibration_of(log: HandLogData) -> Any:
    """The calibration a log was recorded with (``extra.calibration``), else the default for its
    space."""
    from mimicrete.kin import Calibration

    extra = log.header.get("extra") or {}
    if isinstance(extra, dict) and isinstance(extra.get("calibration"), dict):
        return Calibration.from_dict(extra["calibration"])
    space = str(log.header.get("space", "openxr"))
    if space == "robot_base":
        return Calibration(np.eye(3), np.zeros(3), 1.0, "robot_base")
    return Calibration(space="openxr" if space in ("openxr", "webxr") else space)


def load_log(path: str | os.PathLike[str]) -> HandLogData:
    """Parse a hand log for conversion: :func:`mimicrete.handlog.parse` (strict), and at least
    one frame. Raises ``mimicrete.LogFormatError`` (``file:line: reason``)."""
    log = handlog.parse(path, "strict")
    _require_frames(log, os.fspath(path))
    return log


def _require_frames(log: HandLogData, source: str) -> None:
    if len(log) == 0:
        from mimicrete import _native

        raise _native.log_format_error(source, 2, "no frames")


def convert_log(
    log: HandLogData | str | os.PathLike[str],
    task: str,
    out_dir: str | Path | None,
    *,
    source: str | os.PathLike[str] | None = None,
    episode_index: int = 0,
    model: gest.GestureModel | None = None,
    backend: Backend | None = None,
) -> EpisodeResult:
    """Run one hand log through the pipeline and the simulator; write its MCAP demo into
    ``out_dir`` (``None``: simulate only).

    ``log`` is a hand-log path (parsed by :func:`load_log`) or an already parsed
    :class:`mimicrete.handlog.HandLogData`; ``source`` names it (messages, the demo's file name and
    metadata; default: the path, else ``"handlog"``)."""
    if not isinstance(log, HandLogData):
        source = source if source is not None else log
        log = load_log(log)
    source = os.fspath(source) if source is not None else "handlog"
    _require_frames(log, source)
    backend = backend or Backend()
    task = canonical_task(task)
    logged = log.header.get("task")
    if logged is not None and canonical_task(str(logged)) != task:
        raise ValueError(f"{source}: hand log is for task {logged!r}, converting as {task!r}")
    seed = int(log.header.get("episode_seed") or 0)
    calib = calibration_of(log)
    tele = Teleop(
        task,
        log.header["layout"],
        log.header["handedness"],
        calib,
        model,
        backend.hand_to_target_for(calib),
    )
    env = backend.make_env(task)
    obs, _ = env.reset(seed=seed)
    fd = backend.obs_frame_dim(task)
    dt, max_step = backend.control_dt, backend.max_joint_step
    act_dim = 8 if task == "screw" else 7
    q = np.asarray(obs[-fd:][:6], dtype=np.float64)
    q_ik = q.copy()
    sink = None
    out_path = None
    if out_dir is not None:
        out_path = Path(out_dir) / (Path(source).name.split(".")[0] + ".mcap")
        sink = backend.open_writer(out_path, task, seed, episode_index, log, tele.model, source)
    t0 = float(log.t[0])
    k = 0  # frames consumed
    n = len(log.t)
    step = 0
    rewards: list[float] = []
    actions: list[np.ndarray] = []
    picked = installed = fell = terminated = truncated = False
    counts = tele.counts
    try:
        while True:
            t_ctrl = t0 + step * dt
            while k < n and log.t[k] <= t_ctrl + 1e-9:
                before = tele.smoother.state
                tele.push(float(log.t[k]), bool(log.tracked[k]), log.joints[k])
                if sink is not None:
                    te = float(log.t[k]) - t0
                    sink.hand(te, log.joints[k], bool(log.tracked[k]), float(log.t[k]))
                    if tele.smoother.state != before:
                        sink.event(te, "gesture", {"from": before or "", "to": tele.smoother.state})
                k += 1
            if k >= n and t_ctrl > float(log.t[-1]) + dt:
                break  # the log has ended
            a = np.zeros(act_dim, dtype=np.float32)
            if tele.target is not None:
                try:
                    sol = backend.ik(tele.target, q_ik)
                    if np.max(np.abs(wrap_to_pi(sol - q_ik))) > 1.5:  # a branch flip, not a motion
                        raise ArithmeticError("IK jumped to another branch")
                    q_ik = q_ik + wrap_to_pi(sol - q_ik)
                except ArithmeticError:
                    counts.unreachable += 1
                a[:6] = joint_action(q_ik, q, max_step)
            cmd, spin = tele.command()
            a[6] = recorded_command(task, cmd, obs[-fd:])
            if act_dim == 8:
                a[7] = spin
            # The step record pairs an action with the observation it was chosen from (obs_t,
            # a_t), as BC and GAIL need it; the observation after the step is the next record's.
            obs_before = obs
            obs, reward, terminated, truncated, info = env.step(a)
            q = np.asarray(obs[-fd:][:6], dtype=np.float64)
            rewards.append(float(reward))
            actions.append(a)
            events = []
            if info.get("picked", False) and not picked:
                events.append("pick")
            if info.get("installed", False):
                events.append("install")
            if info.get("fell", False):
                events.append("fall")
            picked = picked or bool(info.get("picked", False))
            installed = installed or bool(info.get("installed", False))
            fell = fell or bool(info.get("fell", False))
            if sink is not None:
                sink.step(
                    step,
                    t_ctrl - t0,
                    obs_before,
                    a,
                    float(reward),
                    bool(terminated),
                    bool(truncated),
                    tele.smoother.state or "",
                    env.snapshot(),
                    events,
                )
            step += 1
            if terminated or truncated:
                break
    except BaseException:
        if sink is not None:
            sink.abandon()
        raise
    counts.steps = step
    counts.frames_after_end = n - k
    if sink is not None:
        sink.close(installed, counts)
    return EpisodeResult(
        source,
        str(out_path) if out_path else None,
        seed,
        step,
        rewards,
        np.array(actions, dtype=np.float32).reshape(-1, act_dim),
        picked,
        installed,
        fell,
        bool(terminated),
        bool(truncated),
        counts,
    )


def replay(
    task: str, seed: int, actions: np.ndarray, backend: Backend | None = None
) -> list[float]:
    """Step a fresh environment reset with ``seed`` through ``actions``; its rewards."""
    backend = backend or Backend()
    env = backend.make_env(canonical_task(task))
    env.reset(seed=int(seed))
    out = []
    for a in np.asarray(actions, dtype=np.float32):
        _, r, term, trunc, _ = env.step(a)
        out.append(float(r))
        if term or trunc:
            break
    return out


class Backend:
    """The simulator, kinematics and demo writer the pipeline drives (``mimicrete.envs``,
    ``mimicrete.kin``, ``mimicrete.demos``: the Rust core through its bindings)."""

    def __init__(self) -> None:
        self.control_dt, self.max_joint_step = sim_constants()

    @staticmethod
    def make_env(task: str) -> SimAdapter:
        return SimAdapter(task)

    @staticmethod
    def obs_frame_dim(task: str) -> int:
        from mimicrete import _native

        return int(_native.sim_constants()["tasks"][SIM_TASK[task]]["obs_frame_dim"])

    @staticmethod
    def hand_to_target_for(calibration: Any) -> Any:
        """The hand → tool0 function for one calibration (bound once, used per frame)."""
        return bound_hand_to_target(calibration)

    @staticmethod
    def ik(target: np.ndarray, seed: np.ndarray) -> np.ndarray:
        from mimicrete import IkError, kin

        try:
            return np.asarray(kin.ik(target, seed=seed, model="ur3"), dtype=np.float64)
        except IkError as e:
            raise ArithmeticError(str(e)) from None

    def open_writer(
        self,
        path: Path,
        task: str,
        seed: int,
        episode: int,
        log: HandLogData,
        model,
        source: str = "handlog",
    ) -> Any:
        """A writer for one episode's MCAP demo at ``path`` (its metadata from the log)."""
        meta = {
            "episode": int(episode),
            "task": SIM_TASK[task],
            "seed": int(seed),
            "robot_model": "ur3",
            "source_handlog": str(source),
            "gesture_model": f"svm-{model.task} ({'/'.join(model.classes)})",
            "control_dt": float(self.control_dt),
            "hand": {k: log.header[k] for k in ("layout", "space", "handedness")},
            "extra": {"converter": "mimicrete convert", "hand_rate_hz": _rate(log)},
        }
        return _DemoSink(path, meta)


class _DemoSink:
    """Writes one episode through ``mimicrete.demos.DemoWriter`` (the Rust demo-log writer)."""

    def __init__(self, path: Path, meta: dict[str, Any]) -> None:
        from mimicrete import demos

        path.parent.mkdir(parents=True, exist_ok=True)
        self.w = demos.DemoWriter(str(path), meta)

    def hand(self, t: float, joints: np.ndarray, tracked: bool, hand_t: float) -> None:
        self.w.write_hand_frame(t, np.ascontiguousarray(joints, dtype=np.float64), tracked, hand_t)

    def event(self, t: float, name: str, props: dict[str, Any]) -> None:
        self.w.write_event(t, name, {k: str(v) for k, v in props.items()})

    def step(
        self, step, t, obs, action, reward, terminated, truncated, gesture, snap, events
    ) -> None:
        """One env step; ``snap`` is the simulator's snapshot after it (f64 joints, poses)."""

        def pose(p: dict[str, Any]) -> list[float]:
            return [*map(float, p["t"]), *map(float, p["q"])]

        self.w.write_step(
            step,
            t,
            np.ascontiguousarray(obs, dtype=np.float32),
            np.ascontiguousarray(action, dtype=np.float32),
            reward,
            terminated,
            truncated,
            gesture,
            [float(x) for x in snap["q"]],
            pose(snap["tool0"]),
            pose(snap["object"]),
            events,
        )

    def close(self, success: bool, counts: Counts) -> None:
        self.w.finish(success, {k: json.dumps(v) for k, v in counts.as_dict().items()})

    def abandon(self) -> None:
        self.w.abandon()


def _rate(log: HandLogData) -> float:
    d = np.diff(log.t)
    d = d[d > 0]
    return float(1.0 / np.median(d)) if len(d) else 0.0


# ----------------------------------------------------------------------------------------------
# CLI
# ----------------------------------------------------------------------------------------------


def find_logs(path: str | Path) -> list[Path]:
    """A hand log, or every ``*.jsonl`` in a directory (sorted)."""
    p = Path(path)
    if p.is_dir():
        logs = sorted(p.glob("*.jsonl"))
        if not logs:
            raise FileNotFoundError(f"{p}: no *.jsonl hand logs")
        return logs
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file or directory")
    return [p]


def configure(parser: argparse.ArgumentParser) -> None:
    """Flags of ``mimicrete convert``."""
    parser.add_argument(
        "source", metavar="HANDLOG_OR_DIR", help="a hand log (.jsonl) or a directory of them"
    )
    parser.add_argument(
        "--task",
        required=True,
        choices=["suction", "grip", "screw"],
        help="the task the hand logs demonstrate",
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="where the MCAP demos go")
    parser.add_argument(
        "--gesture-model",
        metavar="PATH",
        help="gesture model (default: the shipped one for the task)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    """Run ``mimicrete convert``; prints per-file outcomes and a summary."""
    from tqdm import tqdm

    try:
        logs = find_logs(args.source)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    model = gest.load_model(args.gesture_model) if args.gesture_model else None
    backend = Backend()
    results = []
    failed = 0
    for i, path in enumerate(tqdm(logs, desc="convert", unit="log", disable=args.no_progress)):
        try:
            res = convert_log(
                path, args.task, args.out, episode_index=i, model=model, backend=backend
            )
        except (LogFormatError, ValueError) as e:
            failed += 1
            tqdm.write(f"error: {e}", file=sys.stderr)
            continue
        results.append(res)
        c = res.counts
        tqdm.write(
            f"{path.name}: {res.steps} steps, "
            f"{'installed' if res.installed else 'NOT installed'}"
            f"{', picked' if res.picked else ''}{', fell' if res.fell else ''}; frames "
            f"{c.frames} (untracked {c.untracked}, degenerate {c.degenerate}), unreachable "
            f"{c.unreachable} steps, {c.gesture_changes} gesture changes"
        )
    if results:
        n_ok = sum(r.installed for r in results)
        print(
            f"{len(results)} demos in {args.out}: {n_ok} installed "
            f"({100.0 * n_ok / len(results):.1f} %), {failed} logs failed"
        )
    return 0 if failed == 0 and results else 1
