"""The gates every command passes, on every backend (so a shadow log shows what live mode would
have refused).

Before the first command (:meth:`Gates.check_start`): every joint within
:data:`START_TOLERANCE` rad of the task spec's ``home_q`` (the message names the joint and its
angle) and the controller's safety mode NORMAL.

On every tick, of the state read (:meth:`Gates.check_state`; a failure stops the run with its
reason): the connection alive, the safety mode still NORMAL (a protective stop, a safeguard stop,
an emergency stop, reduced mode ...), the robot's clock advancing (a stalled stream: no new state
within the deadline), no joint jump between two reads (more than :data:`JUMP_STEPS` joint steps:
something moved the arm, or the stream skipped).

Of every joint target (:meth:`Gates.gate_command`; a gate that fires changes the command, the run
goes on, the tick's log names the gate):

* ``non_finite``: a target that is not a number holds the arm where it is;
* ``joint_step``: each joint moves at most the spec's ``joint_step`` from where it was read;
* ``speed``: at most ``speed_cap`` rad/s (below the arm's rated joint speeds,
  :data:`RATED_SPEED`) over one control period;
* ``workspace``: the TCP of the target inside the spec's box (over the table's extent, at least
  ``z_margin`` above the table top, within ``reach_share`` of the arm's reach); a target outside
  holds the arm where it is.

The host-side deadline (2 control periods without a new command) is the control loop's
(:mod:`.deploy`) and the live streamer's (:mod:`.rtde`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mimicrete import _native
from mimicrete._native import MimicreteError

from . import NORMAL, RobotState, safety_mode_name

#: the farthest (rad) any joint may be from the spec's home_q when a run starts
START_TOLERANCE = 0.5
#: a read joint that moved more than this many joint steps since the last read is a jump
JUMP_STEPS = 3.0
#: the control loop's deadline, in control periods
DEADLINE_PERIODS = 2
JOINT_NAMES = ("base", "shoulder", "elbow", "wrist 1", "wrist 2", "wrist 3")

_PI = math.pi
#: the arms' rated joint speeds (rad/s), base to wrist 3, from Universal Robots' data sheets
RATED_SPEED: dict[str, tuple[float, ...]] = {
    "ur3": (_PI, _PI, _PI, 2 * _PI, 2 * _PI, 2 * _PI),
    "ur3e": (_PI, _PI, _PI, 2 * _PI, 2 * _PI, 2 * _PI),
    "ur5": (_PI,) * 6,
    "ur5e": (_PI,) * 6,
    "ur10": (2 * _PI / 3, 2 * _PI / 3, _PI, _PI, _PI, _PI),
    "ur10e": (2 * _PI / 3, 2 * _PI / 3, _PI, _PI, _PI, _PI),
}
#: the default speed cap (rad/s): at most this, and at most half the slowest rated joint speed
DEFAULT_SPEED_CAP = 1.0


class StartRefused(MimicreteError):
    """The arm is not where a run may start, or the controller is not in normal mode."""


class Stop(MimicreteError):
    """The run must stop; ``reason`` is what the log and the user are told."""

    def __init__(self, reason: str, kind: str) -> None:
        super().__init__(reason)
        self.reason = reason
        #: a short name: safety_mode, connection, stalled, joint_jump, deadline, policy, ...
        self.kind = kind


@dataclass
class Limits:
    """The numbers the gates use, read from a task spec (:meth:`from_spec`)."""

    model: str
    home_q: np.ndarray
    joint_step: float
    tcp_z: float
    period: float
    speed_cap: float
    box_lo: np.ndarray  # x, y, z (m, Base frame)
    box_hi: np.ndarray
    shoulder: np.ndarray  # the reach is measured from here
    reach: float
    start_tolerance: float = START_TOLERANCE
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_spec(
        cls,
        spec: dict[str, Any],
        joint_step: float,
        period: float = 0.04,
        speed_cap: float | None = None,
        z_margin: float = 0.005,
        reach_share: float = 0.95,
    ) -> Limits:
        model = str(spec["robot"]["model"])
        rated = min(RATED_SPEED[model])
        cap = min(DEFAULT_SPEED_CAP, rated / 2) if speed_cap is None else float(speed_cap)
        if not 0 < cap <= rated / 2:
            raise ValueError(
                f"--speed-cap: {cap} rad/s; it must be above 0 and at most half the {model}'s "
                f"slowest rated joint speed ({rated / 2:.3f} rad/s)"
            )
        table = spec["table"]
        hx, hy = float(table["half_extents"][0]), float(table["half_extents"][1])
        top = float(table["top_z"])
        dh = _native.kin_dh(model)
        reach = float(dh["reach"]) * reach_share
        return cls(
            model=model,
            home_q=np.asarray(spec["robot"]["home_q"], np.float64),
            joint_step=float(joint_step),
            tcp_z=float(spec["effector"].get("tcp_z") or 0.0),
            period=float(period),
            speed_cap=cap,
            box_lo=np.array([-hx, -hy, top + z_margin]),
            box_hi=np.array([hx, hy, top + float(dh["reach"])]),
            shoulder=np.array([0.0, 0.0, float(dh["d1"])]),
            reach=reach,
        )

    @property
    def deadline(self) -> float:
        return DEADLINE_PERIODS * self.period

    def tcp_of(self, q: np.ndarray) -> np.ndarray:
        """The TCP position (m, Base) at joint angles ``q``: tool0 by FK, then ``tcp_z`` along
        its z axis (the cup lips' centre)."""
        T = _native.kin_fk(np.asarray(q, np.float64), self.model)
        return T[:3, 3] + T[:3, 2] * self.tcp_z

    def outside(self, p: np.ndarray) -> str | None:
        """Why TCP position ``p`` is outside the workspace, or None."""
        for i, axis in enumerate("xyz"):
            if p[i] < self.box_lo[i] - 1e-12:
                return f"TCP {axis} {p[i]:.3f} m below {self.box_lo[i]:.3f}"
            if p[i] > self.box_hi[i] + 1e-12:
                return f"TCP {axis} {p[i]:.3f} m above {self.box_hi[i]:.3f}"
        d = float(np.linalg.norm(p - self.shoulder))
        if d > self.reach:
            return f"TCP {d:.3f} m from the shoulder, beyond the reach limit {self.reach:.3f}"
        return None


class Gates:
    """The per-run gate state: the last read, when the robot's clock last moved, counts of each
    gate fired."""

    def __init__(self, limits: Limits) -> None:
        self.limits = limits
        self.prev: RobotState | None = None
        self.clock_moved_at: float | None = None
        self.counts: dict[str, int] = {}

    # --- before the first command -----------------------------------------------------------

    def check_start(self, s: RobotState) -> None:
        L = self.limits
        if not s.connected:
            raise StartRefused("the robot is not connected")
        if s.safety_mode != NORMAL:
            raise StartRefused(
                f"safety mode is {safety_mode_name(s.safety_mode)}, not NORMAL: clear it on the "
                "pendant first"
            )
        off = np.abs(_wrap(s.q - L.home_q))
        j = int(np.argmax(off))
        if not np.all(np.isfinite(s.q)) or off[j] > L.start_tolerance:
            raise StartRefused(
                f"joint {j} ({JOINT_NAMES[j]}) is at {s.q[j]:.3f} rad, {off[j]:.3f} rad from the "
                f"spec's home_q {L.home_q[j]:.3f} (at most {L.start_tolerance} allowed): move the "
                "arm to home_q first"
            )

    # --- every tick, the state read ---------------------------------------------------------

    def check_state(self, s: RobotState) -> None:
        L = self.limits
        if not s.connected:
            raise Stop("connection lost: the controller's stream closed", "connection")
        if s.safety_mode != NORMAL:
            raise Stop(f"safety mode changed to {safety_mode_name(s.safety_mode)}", "safety_mode")
        prev = self.prev
        if prev is None or s.robot_time != prev.robot_time:
            self.clock_moved_at = s.read_at
        elif self.clock_moved_at is not None and s.read_at - self.clock_moved_at > L.deadline:
            raise Stop(
                f"stream stalled: no new state from the controller for "
                f"{1000 * (s.read_at - self.clock_moved_at):.0f} ms "
                f"(deadline {1000 * L.deadline:.0f} ms)",
                "stalled",
            )
        if prev is not None:
            jump = np.abs(_wrap(s.q - prev.q))
            j = int(np.argmax(jump))
            if jump[j] > JUMP_STEPS * L.joint_step:
                raise Stop(
                    f"joint jump: joint {j} ({JOINT_NAMES[j]}) moved {jump[j]:.3f} rad between "
                    f"two reads (at most {JUMP_STEPS * L.joint_step:.3f})",
                    "joint_jump",
                )
        self.prev = s

    # --- every command ----------------------------------------------------------------------

    def gate_command(self, q_read: np.ndarray, target: np.ndarray) -> tuple[np.ndarray, list[str]]:
        """The joint target after the gates, and the gates that fired."""
        L = self.limits
        fired: list[str] = []
        q = np.asarray(target, np.float64).copy()
        if not np.all(np.isfinite(q)):
            fired.append("non_finite")
            q = q_read.copy()
        step = np.clip(q - q_read, -L.joint_step, L.joint_step)
        if np.any(np.abs(q - q_read) > L.joint_step + 1e-9):
            fired.append("joint_step")
        lim = L.speed_cap * L.period
        if np.any(np.abs(step) > lim + 1e-9):
            fired.append("speed")
            step = np.clip(step, -lim, lim)
        q = q_read + step
        why = L.outside(L.tcp_of(q))
        if why is not None:
            fired.append("workspace")
            q = q_read.copy()
        for g in fired:
            self.counts[g] = self.counts.get(g, 0) + 1
        return q, fired


def _wrap(d: np.ndarray) -> np.ndarray:
    return (np.asarray(d, np.float64) + np.pi) % (2 * np.pi) - np.pi
