"""Meeting a real robot: one small interface to an arm and three backends behind it.

* ``sim``: the Rapier arm of the run's task (:mod:`.sim`), for tests and rehearsal;
* ``shadow``: a real UR controller read through ur-rtde's ``RTDEReceiveInterface``; every command
  is computed, gated and logged, and **nothing is sent** (:mod:`.rtde`);
* ``live``: the same reads, and the gated joint targets streamed with ``servoJ`` at the
  controller's rate under ur-rtde's watchdog (:mod:`.rtde`). Live mode has been tested against
  the simulated arm and a recording sink only; it has not met a real arm here (docs/deploy.md).

ur-rtde (``pip install mimicrete[robot]``) is imported only inside the backends that talk to a
controller. The gates every command passes are in :mod:`.gates`, the observation a policy is fed
in :mod:`.observe`, where the tile is in :mod:`.tile_pose`, and the control loop that ties them
together and logs every tick as a demo in :mod:`.deploy`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from mimicrete._native import MimicreteError

__all__ = [
    "SAFETY_MODES",
    "NORMAL",
    "Robot",
    "RobotError",
    "RobotState",
    "safety_mode_name",
]

#: The UR controller's safety modes (RTDE ``safety_mode``).
SAFETY_MODES: dict[int, str] = {
    1: "NORMAL",
    2: "REDUCED",
    3: "PROTECTIVE_STOP",
    4: "RECOVERY",
    5: "SAFEGUARD_STOP",
    6: "SYSTEM_EMERGENCY_STOP",
    7: "ROBOT_EMERGENCY_STOP",
    8: "VIOLATION",
    9: "FAULT",
    10: "VALIDATE_JOINT_ID",
    11: "UNDEFINED_SAFETY_MODE",
    12: "AUTOMATIC_MODE_SAFEGUARD_STOP",
    13: "SYSTEM_THREE_POSITION_ENABLING_STOP",
}
NORMAL = 1


def safety_mode_name(mode: int) -> str:
    return f"{SAFETY_MODES.get(int(mode), 'UNKNOWN')} ({int(mode)})"


class RobotError(MimicreteError):
    """A robot that cannot be reached or used (connection refused, ur-rtde missing)."""


@dataclass(frozen=True)
class RobotState:
    """One read of the robot. ``q``: joint angles (rad); ``tcp``: the TCP pose the controller
    reports (x, y, z m, rotation vector rad; Base frame); ``robot_time``: the controller's clock
    (s); ``read_at``: the host's ``time.monotonic()`` when the read returned."""

    q: np.ndarray
    tcp: np.ndarray
    safety_mode: int
    digital_out: int
    digital_in: int
    robot_time: float
    connected: bool
    read_at: float


class Robot(Protocol):
    """What the control loop needs of an arm."""

    #: ``sim``, ``shadow`` or ``live``
    backend: str
    #: whether :meth:`send_joint_target` moves anything (False in shadow mode)
    sends: bool

    def read(self) -> RobotState:
        """The latest state (never blocks for long)."""
        ...

    def send_joint_target(self, q: np.ndarray, suction: bool) -> None:
        """Move towards joint angles ``q`` (rad) in the next control period; suction output on or
        off."""
        ...

    def stop(self, reason: str) -> None:
        """Stop the arm (servoStop, then stopScript on a controller); idempotent."""
        ...

    def close(self) -> None:
        """Let go of the connection (after :meth:`stop`)."""
        ...
