"""The teleoperation session: one episode of a tracked hand driving the UR3 (paper §3.2).

Every hand frame, from a file (``mimicrete convert``) or live (``mimicrete teleop``), goes through
:meth:`Session.push`, and nothing else drives the robot. The gesture is read here (the task's SVM,
:mod:`mimicrete.gestures`, and a hysteresis smoother, so a single misread frame never changes the
end-effector command); everything after it runs in Rust, one call per frame: teleop-core's
``Session`` (``crates/teleop-core``) filters the wrist / index-proximal / middle-proximal joints
(One Euro), maps them to a tool0 target through the calibration, runs the control steps that fell
due at the simulator's rate in the hand's own clock (IK warm-started and unwrapped, the joint
action ``clip((q_ik − q) / joint_step, −1, 1)`` with the env's joint step, its task spec's
``robot.joint_step`` or ``MAX_JOINT_STEP``, the gesture's command, one simulator step)
and records each into the demo. Its documentation there says how, step by step.

Frames the pipeline cannot use are counted, never turned into made-up motion: untracked frames
and degenerate hands keep the last target; an unreachable target (IK fails, or jumps to another
branch) keeps the last solution. Because the live server and the converter run this same code in
the same clock, a hand log saved live converts offline to the same steps, actions and rewards.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from mimicrete import _native, kin, tasks
from mimicrete import gestures as gest
from mimicrete.hands.layouts import check_layout

CONTROL_DT = tasks.CONTROL_DT
#: The default joint motion per step at full action (rad); a session's env may run its task
#: spec's ``robot.joint_step`` instead (``SimEnv.joint_step``), and teleop-core divides by that.
MAX_JOINT_STEP = tasks.MAX_JOINT_STEP
#: Largest joint change (rad) an IK answer may ask for in one step before it counts as a jump to
#: another branch (unreachable), not a motion (teleop-core's).
BRANCH_JUMP: float = float(_native.TELEOP_BRANCH_JUMP)
#: Gesture class → (end-effector command, spin) (tile-sim action a[6], a[7]; teleop-core's table).
COMMANDS: dict[str, tuple[float, float]] = {
    g: (float(c), float(s)) for g, c, s in _native.teleop_gesture_commands()
}


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
    why: str | None  # why the arm did not move toward the hand: "no hand yet", "target unreachable"

    @property
    def following(self) -> bool:
        """The arm moved toward the hand's target this step."""
        return self.why is None


class Recorder(Protocol):
    """Where a session's episode goes: ``teleop.record.DemoSink``, whose ``w`` (the Rust demo-log
    writer) the Rust session writes every hand frame and step into."""

    @property
    def w(self) -> Any: ...


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
        recorder: where steps and hand frames are written (None: nowhere).
        task_file: a task spec file running ``task``'s logic (its object, target, starts and
            thresholds; :func:`mimicrete.tasks.load_task_file`); None: the built-in task.
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
        mapping: str = "absolute",
        task_file: str | None = None,
    ) -> None:
        self.task = tasks.get(task)
        self.task_file = task_file
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
        self.core = _native.TeleopSession(
            self.task.sim,
            self.layout,
            handedness,
            kin.calibration_parts(calibration),
            self.seed,
            None if recorder is None else recorder.w,
            mapping,
            task_file,
        )
        #: ``absolute`` (the tool goes where the hand is: the paper's, and every hand log that
        #: names no mapping) or ``clutch`` (the tool moves by the hand's motion since the clutch
        #: engaged, along a bounded path: the live server's; teleop-core's ``clutch.rs``)
        self.mapping = mapping
        self.raw_gesture: str | None = None
        self.margin: float | None = None  # the SVM's decision margin of raw_gesture
        #: the page's view after the newest :meth:`push` with ``view=True``
        self.view: dict[str, Any] | None = None
        self._done = False  # kept from the steps, so a frame costs one call into Rust

    # ------------------------------------------------------------------ state

    @property
    def gesture(self) -> str | None:
        """The smoothed gesture (what the end effector obeys)."""
        return self.smoother.state

    @property
    def target(self) -> np.ndarray | None:
        """tool0's target (4, 4) in Base from the newest usable frame (None before one)."""
        return self.core.target

    @property
    def counts(self) -> Counts:
        return Counts(**self.core.counts)

    @property
    def engaged(self) -> bool:
        """The clutch is engaged (always False under the absolute mapping)."""
        return bool(self.core.engaged)

    @property
    def step_index(self) -> int:
        return int(self.core.step_index)

    @property
    def last_tracked(self) -> bool | None:
        """The newest frame's tracked flag."""
        return self.core.last_tracked

    @property
    def last_why(self) -> str | None:
        """Why the newest control step did not follow the hand (None: it did, or none yet)."""
        return self.core.last_why

    @property
    def obs(self) -> np.ndarray:
        """The newest observation."""
        return self.core.observation

    def outcome(self) -> Outcome:
        return Outcome(**self.core.outcome)

    @property
    def picked(self) -> bool:
        return bool(self.core.outcome["picked"])

    @property
    def installed(self) -> bool:
        return bool(self.core.outcome["installed"])

    @property
    def fell(self) -> bool:
        return bool(self.core.outcome["fell"])

    @property
    def terminated(self) -> bool:
        return bool(self.core.outcome["terminated"])

    @property
    def truncated(self) -> bool:
        return bool(self.core.outcome["truncated"])

    @property
    def done(self) -> bool:
        """The episode has ended (terminated by the task or truncated at its step limit)."""
        return self._done

    def command(self) -> tuple[float, float]:
        """The end-effector command and spin for the current smoothed gesture (0, 0 before any)."""
        return self.core.command

    def snapshot(self) -> dict[str, Any]:
        """The simulator's state now (joints, tool0, object, end effector)."""
        return self.core.snapshot()

    def scene_entities(self) -> list[dict[str, Any]]:
        """The Foxglove scene of the episode (its start's pad, target, plate)."""
        return self.core.scene_entities()

    def set_calibration(self, calibration: Any, shift: np.ndarray | None = None) -> None:
        """Use another calibration from the next frame on; ``shift`` (Base, m) moves the current
        target with it (a calibration that differs by a translation moves every target by it)."""
        self.calibration = calibration
        sh = None if shift is None else [float(x) for x in np.asarray(shift, dtype=np.float64)]
        self.core.set_calibration(kin.calibration_parts(calibration), sh)

    # ------------------------------------------------------------------ input

    def push(
        self,
        t: float,
        tracked: bool,
        joints: np.ndarray,
        view: bool = False,
        clutch: str | None = None,
    ) -> list[Step]:
        """Feed one hand frame at time ``t`` (seconds, any origin, non-decreasing).

        Runs every control step that fell due before the frame (their results are returned),
        then updates the gesture and the target from it. Frames after the episode has ended
        are counted and ignored. ``view``: also take what the page draws (:attr:`view`).
        ``clutch``: ``engage`` / ``release`` at this frame (the clutch mapping)."""
        joints, raw = self._read(tracked, joints)
        steps, v = self.core.push(
            float(t), bool(tracked), joints, raw, self.smoother.state, view, clutch
        )
        self.view = v
        return self._steps(steps)

    def _steps(self, steps: list[tuple[Any, ...]]) -> list[Step]:
        out = [Step(*s) for s in steps]
        if out and (out[-1].terminated or out[-1].truncated):
            self._done = True
        return out

    def observe(
        self, t: float, tracked: bool, joints: np.ndarray, clutch: str | None = None
    ) -> None:
        """The hand half of :meth:`push` alone: update the gesture and the target from one frame
        (and record it), without running the control steps that fell due."""
        joints, raw = self._read(tracked, joints)
        self.core.observe(float(t), bool(tracked), joints, raw, self.smoother.state, clutch)

    def _read(self, tracked: bool, joints: np.ndarray) -> tuple[np.ndarray, str | None]:
        """The frame's joints as Rust takes them and its gesture (None: untracked, degenerate,
        or the episode is over); the smoother takes it in."""
        joints = np.ascontiguousarray(joints, dtype=np.float64)
        raw = None
        if tracked and not self.done:
            raw, self.margin = self.model.predict_margin(joints, self.handedness, self.layout)
            self.raw_gesture = raw
            self.smoother.update(raw)
        return joints, raw

    def finish(self) -> list[Step]:
        """The hand stream has ended: run the control steps up to one control period past the
        last frame (as the converter always has), unless the episode ended before."""
        self.view = None
        return self._steps(self.core.finish())
