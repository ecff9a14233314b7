"""The backends that talk to a UR controller through ur-rtde (imported here only; pinned in the
``robot`` extra: ``pip install mimicrete[robot]``).

``shadow``: ``RTDEReceiveInterface`` reads the state (an explicit list of outputs,
:data:`OUTPUTS`, at the controller's rate: ur-rtde asks for 500 Hz of an e-Series controller,
125 Hz of a CB3, from the version the controller reports); every command is computed, gated and
logged by the control loop, and nothing is ever sent.

``live``: the same reads; the gated joint targets (25 Hz) go to a :class:`ServoStreamer`, which
interpolates them at the controller's step time (``getStepTime()``: 2 ms e-Series, 8 ms CB3)
under the speed cap and streams ``servoJ``; ur-rtde's watchdog is armed and kicked by every
command; a host-side deadline (no new target for 2 control periods) stops the arm from the
streamer's own thread. Stop: ``servoStop`` then ``stopScript``; the suction output is left as it
is unless ``release_on_stop``. **Live mode has been tested against the simulated arm and a
recording sink only; it has not met a real arm** (docs/deploy.md).
"""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from . import RobotError, RobotState

#: the RTDE outputs the receive interface asks for (ur-rtde's default recipe asks for 58)
OUTPUTS = [
    "timestamp",
    "actual_q",
    "actual_TCP_pose",
    "safety_mode",
    "actual_digital_output_bits",
    "actual_digital_input_bits",
]

#: how long to wait for the controller's first data package after connecting (s)
FIRST_DATA_TIMEOUT = 2.0
#: servoJ's look-ahead time (s) and gain: ur-rtde's documented defaults' middle ground
SERVO_LOOKAHEAD = 0.1
SERVO_GAIN = 300.0
#: ur-rtde's watchdog: the control script stops the arm if not kicked at this rate (Hz)
WATCHDOG_HZ = 10.0


def _import(name: str) -> Any:
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError as e:
        raise RobotError(
            f"the {name} module of ur-rtde is missing: pip install 'mimicrete[robot]' "
            f"(ur-rtde==1.6.5) ({e})"
        ) from None


class RtdeReader:
    """The robot's state through ``RTDEReceiveInterface`` (or any object with its getters)."""

    def __init__(self, host: str | None = None, receive: Any = None) -> None:
        if receive is None:
            rtde_receive = _import("rtde_receive")
            try:
                receive = rtde_receive.RTDEReceiveInterface(host, -1.0, OUTPUTS)
            except RuntimeError as e:
                raise RobotError(f"--host {host}: cannot read the controller ({e})") from None
            # the first data package: until it comes, the getters return zeros
            end = time.monotonic() + FIRST_DATA_TIMEOUT
            while receive.getTimestamp() <= 0.0:
                if time.monotonic() > end:
                    receive.disconnect()
                    raise RobotError(
                        f"--host {host}: connected, but no data from the controller within "
                        f"{FIRST_DATA_TIMEOUT:.0f} s"
                    )
                time.sleep(0.002)
        self.receive = receive

    def read(self) -> RobotState:
        r = self.receive
        connected = bool(r.isConnected())
        return RobotState(
            q=np.asarray(r.getActualQ(), np.float64),
            tcp=np.asarray(r.getActualTCPPose(), np.float64),
            safety_mode=int(r.getSafetyMode()),
            digital_out=int(r.getActualDigitalOutputBits()),
            digital_in=int(r.getActualDigitalInputBits()),
            robot_time=float(r.getTimestamp()),
            connected=connected,
            read_at=time.monotonic(),
        )

    def close(self) -> None:
        try:
            if self.receive.isConnected():
                self.receive.disconnect()
        except RuntimeError:
            pass


class ShadowRobot:
    """Reads a real controller; sends nothing. ``would_send`` keeps the last command computed."""

    backend = "shadow"
    sends = False

    def __init__(self, host: str | None = None, reader: RtdeReader | None = None) -> None:
        self.reader = reader or RtdeReader(host)
        self.would_send: tuple[np.ndarray, bool] | None = None
        self.stopped: str | None = None

    def read(self) -> RobotState:
        return self.reader.read()

    def send_joint_target(self, q: np.ndarray, suction: bool) -> None:
        self.would_send = (np.asarray(q, np.float64).copy(), bool(suction))

    def stop(self, reason: str) -> None:
        if self.stopped is None:
            self.stopped = reason

    def close(self) -> None:
        self.reader.close()


class ServoStreamer(threading.Thread):
    """Streams ``servoJ`` at the controller's step time towards the latest target: each target
    is reached over one control period by equal steps, each step at most ``speed_cap * step_time``
    per joint. No new target within ``deadline`` s: ``servoStop`` and the streamer ends
    (``deadline_missed`` set)."""

    def __init__(
        self,
        control: Any,
        q0: np.ndarray,
        step_time: float,
        period: float,
        speed_cap: float,
        deadline: float,
    ) -> None:
        super().__init__(daemon=True, name="servoJ")
        self.control = control
        self.step_time = float(step_time)
        self.period = float(period)
        self.max_step = float(speed_cap) * self.step_time
        self.deadline = float(deadline)
        self.setpoint = np.asarray(q0, np.float64).copy()
        self._target = self.setpoint.copy()
        self._per_step = np.zeros(6)
        self._target_at = time.monotonic()
        self._lock = threading.Lock()
        self._halt = threading.Event()
        self.deadline_missed = threading.Event()
        self.error: BaseException | None = None
        self.servo_calls = 0

    def set_target(self, q: np.ndarray) -> None:
        with self._lock:
            self._target = np.asarray(q, np.float64).copy()
            n = max(1.0, round(self.period / self.step_time))
            self._per_step = np.abs(self._target - self.setpoint) / n
            self._target_at = time.monotonic()

    def halt(self) -> None:
        self._halt.set()
        if self.is_alive() and threading.current_thread() is not self:
            self.join(timeout=1.0)

    def run(self) -> None:
        c = self.control
        period_fn = getattr(c, "initPeriod", None)
        next_t = time.monotonic()
        try:
            while not self._halt.is_set():
                t_start = period_fn() if period_fn is not None else None
                with self._lock:
                    if time.monotonic() - self._target_at > self.deadline:
                        self.deadline_missed.set()
                        c.servoStop()
                        return
                    step = np.clip(self._target - self.setpoint, -self._per_step, self._per_step)
                    step = np.clip(step, -self.max_step, self.max_step)
                    self.setpoint = self.setpoint + step
                    q = [float(x) for x in self.setpoint]
                c.servoJ(q, 0.0, 0.0, self.step_time, SERVO_LOOKAHEAD, SERVO_GAIN)
                self.servo_calls += 1
                if t_start is not None:
                    c.waitPeriod(t_start)
                else:
                    next_t += self.step_time
                    delay = next_t - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
                    else:
                        next_t = time.monotonic()
        except BaseException as e:  # noqa: BLE001 (reported to the control loop)
            self.error = e


class LiveRobot:
    """Reads through ``reader``; moves the arm through ``control`` (``RTDEControlInterface``, or
    in the tests a recording sink driving the simulated arm) and the suction through ``io``
    (``RTDEIOInterface``: standard digital output ``suction_output``)."""

    backend = "live"
    sends = True

    def __init__(
        self,
        reader: Any,
        control: Any,
        io: Any,
        suction_output: int,
        period: float,
        speed_cap: float,
        deadline: float,
        release_on_stop: bool = False,
        step_time: float | None = None,
    ) -> None:
        self.reader = reader
        self.control = control
        self.io = io
        self.suction_output = int(suction_output)
        self.release_on_stop = release_on_stop
        self.step_time = float(step_time if step_time is not None else control.getStepTime())
        self.period = period
        self.speed_cap = speed_cap
        self.deadline = deadline
        self.streamer: ServoStreamer | None = None
        self.suction: bool | None = None
        self.stopped: str | None = None

    @classmethod
    def connect(cls, host: str, **kw: Any) -> LiveRobot:
        rtde_control = _import("rtde_control")
        rtde_io = _import("rtde_io")
        reader = RtdeReader(host)
        try:
            control = rtde_control.RTDEControlInterface(host)
            io = rtde_io.RTDEIOInterface(host)
        except RuntimeError as e:
            reader.close()
            raise RobotError(f"--host {host}: cannot take control ({e})") from None
        return cls(reader, control, io, **kw)

    def read(self) -> RobotState:
        if self.streamer is not None and self.streamer.error is not None:
            raise RobotError(f"servoJ stream failed: {self.streamer.error}")
        return self.reader.read()

    @property
    def deadline_missed(self) -> bool:
        return self.streamer is not None and self.streamer.deadline_missed.is_set()

    def send_joint_target(self, q: np.ndarray, suction: bool) -> None:
        if self.stopped is not None:
            return
        if self.streamer is None:
            self.control.setWatchdog(WATCHDOG_HZ)
            q0 = self.reader.read().q
            self.streamer = ServoStreamer(
                self.control, q0, self.step_time, self.period, self.speed_cap, self.deadline
            )
            self.streamer.set_target(q)
            self.streamer.start()
        else:
            self.streamer.set_target(q)
        self.control.kickWatchdog()
        if suction != self.suction:
            self.io.setStandardDigitalOut(self.suction_output, bool(suction))
            self.suction = bool(suction)

    def stop(self, reason: str) -> None:
        if self.stopped is not None:
            return
        self.stopped = reason
        if self.streamer is not None:
            self.streamer.halt()
        errors = []
        for call in (self.control.servoStop, self.control.stopScript):
            try:
                call()
            except RuntimeError as e:  # a lost connection: the controller's watchdog stops it
                errors.append(str(e))
        if self.release_on_stop and self.suction:
            try:
                self.io.setStandardDigitalOut(self.suction_output, False)
            except RuntimeError as e:
                errors.append(str(e))

    def close(self) -> None:
        for obj in (self.control, self.io):
            fn = getattr(obj, "disconnect", None)
            if fn is not None:
                try:
                    fn()
                except RuntimeError:
                    pass
        self.reader.close()
