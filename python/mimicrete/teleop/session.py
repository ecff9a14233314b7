"""The teleoperation session: one episode of a tracked hand driving the UR3 (paper §3.2).

Every hand frame, from a file (``mimicrete convert``) or live (``mimicrete teleop``), goes through
:meth:`Session.push`, and nothing else drives the robot:

1. gesture per frame (the task's SVM, :mod:`mimicrete.gestures`) and a hysteresis smoother, so a
   single misread frame never changes the end-effector command;
2. the hand frame: the wrist / index-proximal / middle-proximal joints, low-pass filtered with a
   One Euro filter (tracking jitter on knuckles 2 cm apart would otherwise shake the tool),
   mapped to a tool0 target in the robot Base by ur3-kin's ``hand_to_target`` with the
   calibration;
3. the control steps, at the simulator's rate in the hand's own clock: step ``k`` runs at
   ``t0 + k · CONTROL_DT`` with every frame up to that time already pushed (the 90 Hz tracking
   stream is resampled: each step uses the newest filtered hand state at its start time). A
   frame first runs the steps that fell due before it, then updates the hand state;
4. per step, inverse kinematics warm-started from the previous solution and unwrapped next to
   the current joints (no 2π jumps), the joint action ``clip((q_ik − q) / MAX_JOINT_STEP, −1, 1)``,
   the smoothed gesture's command ∈ {−1, 0, +1} (and the spin for screwing; the suction, which
   latches, gets a command only when it switches: :func:`recorded_command`), one simulator step,
   one demo record.

Frames the pipeline cannot use are counted, never turned into made-up motion: untracked frames
and degenerate hands keep the last target; an unreachable target (IK fails) keeps the last
solution. Because the live server and the converter run this same code in the same clock, a hand
log saved live converts offline to the same steps, actions and rewards.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from mimicrete import IkError, MimicreteError, _native, kin, tasks
from mimicrete import gestures as gest
from mimicrete.hands.layouts import FRAME_JOINTS, check_layout

_CONST = _native.sim_constants()
CONTROL_DT: float = float(_CONST["CONTROL_DT"])
MAX_JOINT_STEP: float = float(_CONST["MAX_JOINT_STEP"])
#: Largest joint change (rad) an IK answer may ask for in one step before it counts as a jump to
#: another branch (unreachable), not a motion.
BRANCH_JUMP = 1.5

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
        if self.x is None or self.dx is None or self.t is None or t <= self.t:
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


def joint_action(q_ik: np.ndarray, q: np.ndarray, max_step: float = MAX_JOINT_STEP) -> np.ndarray:
    """``clip(wrap(q_ik − q) / max_step, −1, 1)``: the shortest way round, at most one full step."""
    return np.clip(wrap_to_pi(np.asarray(q_ik) - np.asarray(q)) / max_step, -1.0, 1.0)


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


@dataclass
class Counts:
    """What happened to the frames of one episode."""

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


@dataclass
class Step:
    """One control step: the action chosen from ``obs`` and what the simulator made of it."""

    index: int
    t: float  # seconds since the episode's first frame
    obs: np.ndarray  # the observation the action was chosen from
    action: np.ndarray
    reward: float
    terminated: bool
    truncated: bool
    events: list[str]
    following: bool  # the arm moves toward the hand's target this step
    why: str | None  # why it does not: "no hand yet", "target unreachable"


class Recorder(Protocol):
    """Where a session's episode goes (``teleop.record.DemoSink`` writes an MCAP demo)."""

    def hand(self, t: float, joints: np.ndarray, tracked: bool, hand_t: float) -> None: ...
    def event(self, t: float, name: str, props: dict[str, Any]) -> None: ...
    def step(self, step: Step, gesture: str, snap: dict[str, Any]) -> None:
        """One control step, the smoothed gesture it obeyed ("" before any) and the
        simulator's snapshot after it (``SimEnv.snapshot``)."""


@dataclass
class Outcome:
    """How an episode went, so far or in the end."""

    steps: int
    picked: bool
    installed: bool
    fell: bool
    terminated: bool
    truncated: bool
    total_reward: float


class Session:
    """One episode of teleoperation: hand frames in, control steps out, a demo recorded.

    Args:
        task: ``suction``, ``grip`` or ``screw`` (any spelling :func:`mimicrete.tasks.get` takes).
        layout: joint order of the frames (``webxr``, ``openxr``, ...).
        handedness: ``left`` / ``right``: the hand that drives.
        calibration: tracking space → Base (:class:`mimicrete.kin.Calibration`, a dict, or None
            for ur3-kin's default).
        seed: the simulator seed of the episode (the tile's position).
        model: the gesture model (default: the shipped one for the task).
        recorder: where steps, hand frames and gesture events are written (None: nowhere).
    """

    def __init__(
        self,
        task: str,
        layout: str,
        handedness: str,
        calibration: Any,
        seed: int,
        *,
        model: gest.GestureModel | None = None,
        recorder: Recorder | None = None,
    ) -> None:
        self.task = tasks.get(task)
        self.layout = check_layout(layout)
        if handedness not in ("left", "right"):
            raise ValueError(f"handedness must be 'left' or 'right', got {handedness!r}")
        self.handedness = handedness
        self.calibration = calibration
        self.seed = int(seed)
        self.model = model or gest.load_default(self.task.name)
        self.model.reset()  # a temporal model forgets the previous episode's frames
        self.recorder = recorder
        self.smoother = gest.GestureSmoother(n=7, k=5)
        self.filter = OneEuro(min_cutoff=1.0, beta=2.0)
        self.frame_idx = FRAME_JOINTS[self.layout]
        self._calib = kin._calib(calibration)
        self.env = _native.SimEnv(self.task.sim)
        self.obs = self.env.reset(self.seed)
        fd = self.task.obs_frame_dim
        self.q = np.asarray(self.obs[-fd:][:6], dtype=np.float64)
        self.q_ik = self.q.copy()
        self.target: np.ndarray | None = None
        self.raw_gesture: str | None = None
        self.last_tracked: bool | None = None  # the newest frame's tracked flag
        self.margin: float | None = None  # the SVM's decision margin of raw_gesture
        self.counts = Counts()
        self.t0: float | None = None
        self.t_last: float | None = None
        self.step_index = 0
        self.picked = self.installed = self.fell = False
        self.terminated = self.truncated = False
        self.total_reward = 0.0

    # ------------------------------------------------------------------ state

    @property
    def gesture(self) -> str | None:
        """The smoothed gesture (what the end effector obeys)."""
        return self.smoother.state

    @property
    def done(self) -> bool:
        """The episode has ended (terminated by the task or truncated at its step limit)."""
        return self.terminated or self.truncated

    def command(self) -> tuple[float, float]:
        """The end-effector command and spin for the current smoothed gesture (0, 0 before any)."""
        g = self.smoother.state
        return COMMANDS[g] if g is not None else (0.0, 0.0)

    def outcome(self) -> Outcome:
        return Outcome(
            self.step_index,
            self.picked,
            self.installed,
            self.fell,
            self.terminated,
            self.truncated,
            self.total_reward,
        )

    def set_calibration(self, calibration: Any, shift: np.ndarray | None = None) -> None:
        """Use another calibration from the next frame on; ``shift`` (Base, m) moves the current
        target with it (a calibration that differs by a translation moves every target by it)."""
        self.calibration = calibration
        self._calib = kin._calib(calibration)
        if shift is not None and self.target is not None:
            self.target = self.target.copy()
            self.target[:3, 3] += np.asarray(shift, dtype=np.float64)

    # ------------------------------------------------------------------ input

    def push(self, t: float, tracked: bool, joints: np.ndarray) -> list[Step]:
        """Feed one hand frame at time ``t`` (seconds, any origin, non-decreasing).

        Runs every control step that fell due before the frame (their results are returned),
        then updates the gesture and the target from it. Frames after the episode has ended
        are counted and ignored."""
        if self.t0 is None:
            self.t0 = float(t)
        steps: list[Step] = []
        while not self.done and self._t_ctrl() < t - 1e-9:
            steps.append(self._control_step())
        if self.done:
            self.counts.frames_after_end += 1
            return steps
        self.observe(float(t), bool(tracked), joints)
        return steps

    def finish(self) -> list[Step]:
        """The hand stream has ended: run the control steps up to one control period past the
        last frame (as the converter always has), unless the episode ended before."""
        steps: list[Step] = []
        if self.t_last is None:
            return steps
        while not self.done and self._t_ctrl() <= self.t_last + CONTROL_DT:
            steps.append(self._control_step())
        self.counts.steps = self.step_index
        return steps

    # ------------------------------------------------------------------ internals

    def _t_ctrl(self) -> float:
        assert self.t0 is not None
        return self.t0 + self.step_index * CONTROL_DT

    def observe(self, t: float, tracked: bool, joints: np.ndarray) -> None:
        """The hand half of :meth:`push` alone: update the gesture and the target from one frame
        (and record it), without running control steps."""
        if self.t0 is None:
            self.t0 = float(t)
        c = self.counts
        c.frames += 1
        self.t_last = t
        self.last_tracked = tracked
        assert self.t0 is not None
        before = self.smoother.state
        if self.recorder is not None:
            self.recorder.hand(t - self.t0, joints, tracked, t)
        if not tracked:
            c.untracked += 1
            return
        raw, self.margin = self.model.predict_margin(joints, self.handedness, self.layout)
        self.raw_gesture = raw
        gesture = self.smoother.update(raw)
        if gesture != before:
            if before is not None:
                c.gesture_changes += 1
            if self.recorder is not None:
                self.recorder.event(t - self.t0, "gesture", {"from": before or "", "to": gesture})
        if raw is None:
            c.degenerate += 1
            return
        c.gestures[raw] = c.gestures.get(raw, 0) + 1
        w, i, m = self.frame_idx
        pts = self.filter(np.concatenate([joints[w], joints[i], joints[m]]), t)
        try:
            target = _native.kin_hand_to_target(
                pts[:3], pts[3:6], pts[6:9], self.handedness, self._calib
            )
        except (ValueError, MimicreteError):  # degenerate hand (collinear frame joints)
            c.degenerate += 1
            return
        self.target = np.asarray(target, dtype=np.float64)

    def _control_step(self) -> Step:
        task = self.task
        a = np.zeros(task.act_dim, dtype=np.float32)
        following, why = self.target is not None, None
        if self.target is None:
            why = "no hand yet"
        else:
            try:
                sol = np.asarray(kin.ik(self.target, seed=self.q_ik, model="ur3"))
                if np.max(np.abs(wrap_to_pi(sol - self.q_ik))) > BRANCH_JUMP:
                    raise ArithmeticError("IK jumped to another branch")
                self.q_ik = self.q_ik + wrap_to_pi(sol - self.q_ik)
            except (IkError, ArithmeticError):
                self.counts.unreachable += 1
                following, why = False, "target unreachable"
            a[:6] = joint_action(self.q_ik, self.q)
        fd = task.obs_frame_dim
        cmd, spin = self.command()
        a[6] = recorded_command(task.name, cmd, self.obs[-fd:])
        if task.act_dim == 8:
            a[7] = spin
        # The step record pairs an action with the observation it was chosen from (obs_t, a_t),
        # as BC and GAIL need it; the observation after the step is the next record's.
        obs_before = self.obs
        t = self._t_ctrl() - (self.t0 or 0.0)
        self.obs, reward, self.terminated, self.truncated, info = self.env.step(a)
        self.q = np.asarray(self.obs[-fd:][:6], dtype=np.float64)
        events = []
        if info.get("picked", False) and not self.picked:
            events.append("pick")
        if info.get("installed", False):
            events.append("install")
        if info.get("fell", False):
            events.append("fall")
        self.picked = self.picked or bool(info.get("picked", False))
        self.installed = self.installed or bool(info.get("installed", False))
        self.fell = self.fell or bool(info.get("fell", False))
        self.total_reward += float(reward)
        step = Step(
            self.step_index,
            t,
            obs_before,
            a,
            float(reward),
            bool(self.terminated),
            bool(self.truncated),
            events,
            following,
            why,
        )
        if self.recorder is not None:
            self.recorder.step(step, self.smoother.state or "", self.env.snapshot())
        self.step_index += 1
        self.counts.steps = self.step_index
        return step
