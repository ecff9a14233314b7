"""The live backend's command path against the simulated arm and a recording sink (no real arm
has been driven: docs/deploy.md): the gated targets interpolated and streamed with servoJ under
the speed cap, ur-rtde's watchdog armed and kicked, the suction output switched, the host-side
deadline stopping the stream on its own, and a stop that is servoStop then stopScript."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from mimicrete.learn.run_files import load_policy
from mimicrete.robot import deploy as dep
from mimicrete.robot import gates as gates_mod
from mimicrete.robot.gates import Limits
from mimicrete.robot.rtde import WATCHDOG_HZ, LiveRobot
from mimicrete.robot.sim import SimRobot
from mimicrete.robot.tile_pose import FixedTilePose

from .conftest import TILE

STEP_TIME = 0.008  # a CB3's servo period (ur-rtde: getStepTime())
SUCTION_OUT = 3


class RecordingSink:
    """Stands where RTDEControlInterface and RTDEIOInterface stand: records every call (time,
    name, args) and moves the simulated arm to each servoJ setpoint."""

    def __init__(self, sim: SimRobot, lock: threading.Lock) -> None:
        self.sim, self.lock = sim, lock
        self.calls: list[tuple[float, str, tuple]] = []

    def _rec(self, name, *args):
        self.calls.append((time.monotonic(), name, args))
        return True

    def servoJ(self, q, v, a, dt, lookahead, gain):
        with self.lock:
            self.sim.set_joints(np.asarray(q))
        return self._rec("servoJ", list(q), v, a, dt, lookahead, gain)

    def servoStop(self, a=10.0):
        return self._rec("servoStop", a)

    def stopScript(self):
        return self._rec("stopScript")

    def setWatchdog(self, hz):
        return self._rec("setWatchdog", hz)

    def kickWatchdog(self):
        return self._rec("kickWatchdog")

    def setStandardDigitalOut(self, n, on):
        return self._rec("setStandardDigitalOut", n, on)

    def names(self):
        return [c[1] for c in self.calls]


class LockedReader:
    def __init__(self, sim, lock):
        self.sim, self.lock = sim, lock

    def read(self):
        with self.lock:
            return self.sim.read()

    def close(self):
        pass


@pytest.fixture(scope="module")
def policy_and_task(run_dir):
    actor, cfg = load_policy(run_dir)
    pol = dep.torch_policy(actor)
    pol(np.zeros(80, np.float32))
    return pol, dep.Task.of_run(cfg.env_settings.env_id, None, TILE)


def _live(task, release_on_stop=False, speed_cap=None):
    sim = SimRobot(task="TileSuction", tile_pose=TILE)
    lock = threading.Lock()
    sink = RecordingSink(sim, lock)
    limits = Limits.from_spec(task.spec, task.joint_step, speed_cap=speed_cap)
    robot = LiveRobot(
        LockedReader(sim, lock), sink, sink, SUCTION_OUT, limits.period, limits.speed_cap,
        limits.deadline, release_on_stop=release_on_stop, step_time=STEP_TIME,
    )  # fmt: skip
    return sim, sink, robot, limits


def suction_script(policy, on_from: int, off_from: int | None = None):
    """The policy, with its suction command replaced: on from tick ``on_from``, off from
    ``off_from`` (the switches happen whatever the arm's speed; this tests the output's path)."""
    tick = []

    def act(obs):
        a = policy(obs)
        k = len(tick)
        tick.append(k)
        a[6] = 1.0 if k >= on_from and (off_from is None or k < off_from) else -1.0
        return a

    return act


def test_live_streams_gated_targets_with_servoj(policy_and_task, tmp_path, monkeypatch):
    # What streams and what the gates let through, not how fast this machine is: the deadline
    # (2 control periods, 80 ms) is lifted here, as a pause of the test process (113 ms seen after
    # the other robot tests) would stop the run; the deadline has its own tests (the streamer
    # stopping on its own below, test_shadow's slow policy).
    monkeypatch.setattr(gates_mod, "DEADLINE_PERIODS", 100)
    policy, task = policy_and_task
    sim, sink, robot, limits = _live(task, speed_cap=0.75)
    scripted = suction_script(policy, 30, 50)
    o = dep.run(robot, scripted, task, FixedTilePose(*TILE), tmp_path / "live.mcap",
                limits=limits, ticks=60)  # fmt: skip
    assert o.kind == "ticks", o.reason
    names = sink.names()
    # the watchdog armed once (before the first servoJ), kicked by every command
    assert names.index("setWatchdog") < names.index("servoJ")
    assert [c[2] for c in sink.calls if c[1] == "setWatchdog"] == [(WATCHDOG_HZ,)]
    assert names.count("kickWatchdog") == 60
    # the stop: servoStop, then stopScript, and nothing streamed after it
    assert names[-2:] == ["servoStop", "stopScript"]
    servo = [c for c in sink.calls if c[1] == "servoJ"]
    assert all(c[2][3] == STEP_TIME for c in servo)
    # about one servoJ a servo period over the 60 ticks (2.4 s at 125 Hz: 300; fewer when the
    # machine is loaded: a late servo step is not made up)
    assert 120 <= len(servo) <= 330, len(servo)
    qs = np.array([c[2][0] for c in servo])
    steps = np.abs(np.diff(qs, axis=0))
    assert steps.max() <= 0.75 * STEP_TIME + 1e-9  # the speed cap, per servo step
    ticks = dep_ticks(o.path)
    # each gated command moved at most the cap over a control period
    for t in ticks:
        assert np.abs(np.subtract(t["command_q"], t["q_read"])).max() <= 0.75 * 0.04 + 1e-9
    assert sum("speed" in t["gates"] for t in ticks) > 10  # the cap bit: the policy asks 1 rad/s
    assert all(t["sent"] for t in ticks)
    # the arm went where it was sent: the last setpoint is the last command, nearly reached
    last_cmd = np.asarray(ticks[-1]["command_q"])
    assert np.abs(qs[-1] - last_cmd).max() <= 0.75 * 0.04 + 1e-9
    assert np.abs(np.asarray(sim.read().q) - qs[-1]).max() < 1e-9
    assert np.abs(last_cmd - np.asarray(ticks[0]["q_read"])).max() > 0.1  # it moved
    # the suction output switched with the command: on at tick 30, off at tick 50, one write
    # each (the first command writes the output's state too); nothing more at the stop
    douts = [c[2] for c in sink.calls if c[1] == "setStandardDigitalOut"]
    assert douts == [(SUCTION_OUT, False), (SUCTION_OUT, True), (SUCTION_OUT, False)]
    assert [t["suction"] for t in ticks] == [False] * 30 + [True] * 20 + [False] * 10


def test_release_on_stop_switches_the_suction_off_after_stopping(policy_and_task, tmp_path):
    policy, task = policy_and_task
    sim, sink, robot, limits = _live(task, release_on_stop=True)
    scripted = suction_script(policy, 10)
    o = dep.run(robot, scripted, task, FixedTilePose(*TILE), tmp_path / "live.mcap",
                limits=limits, ticks=20)  # fmt: skip
    ticks = dep_ticks(o.path)
    assert o.kind == "ticks", o.reason
    assert ticks[-1]["suction"]  # holding when it stopped
    assert sink.names()[-3:] == ["servoStop", "stopScript", "setStandardDigitalOut"]
    assert sink.calls[-1][2] == (SUCTION_OUT, False)


def test_the_streamer_stops_the_arm_on_its_own_when_commands_stop(policy_and_task, tmp_path):
    policy, task = policy_and_task
    sim, sink, robot, limits = _live(task)
    calls = []

    def stuck(obs):
        calls.append(1)
        if len(calls) == 10:
            time.sleep(0.3)  # the policy hangs for 7 control periods
        return policy(obs)

    o = dep.run(robot, stuck, task, FixedTilePose(*TILE), tmp_path / "live.mcap",
                limits=limits, ticks=40)  # fmt: skip
    assert o.kind == "deadline", o.reason
    kicks = [c[0] for c in sink.calls if c[1] == "kickWatchdog"]
    stops = [c[0] for c in sink.calls if c[1] == "servoStop"]
    # the streamer's servoStop came within the deadline (+ a servo period or two) of the last
    # command, while the policy still hung (before the control loop could notice)
    assert stops and stops[0] - kicks[-1] <= limits.deadline + 3 * STEP_TIME + 0.02
    assert stops[0] < kicks[-1] + 0.3
    servo = [c[0] for c in sink.calls if c[1] == "servoJ"]
    assert max(servo) < stops[0]  # nothing streamed after it
    assert sink.names()[-1] == "stopScript"


def dep_ticks(path):
    import json

    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(["/deploy/tick"])]


def test_live_through_the_cli_refuses_a_controller_it_cannot_take_over(run_dir, tmp_path):
    """The loopback controller serves RTDE only: ur-rtde's control interface finds no dashboard
    server, and deploy says so in one line, exit 2, before anything is written or sent."""
    import sys
    from pathlib import Path

    from ._rtde_server import LoopbackRobot
    from .conftest import home_q, tcp_of

    sys.path.insert(0, str(Path(__file__).parent.parent))
    from _cli_run import run_cli

    q = home_q()
    with LoopbackRobot(q, tcp=tcp_of(q), version=(5, 21, 0, 0)) as c:
        r = run_cli(
            "deploy", str(run_dir), "--robot", "ur3", "--live", "--host", c.host,
            "--tile-pose", "fixed:{},{},{}".format(*TILE), "--out", str(tmp_path),
        )  # fmt: skip
        log = c.log()["log"]
    assert r.returncode == 2, r.stderr
    assert f"--host {c.host}: cannot take control (" in r.stderr
    assert "Traceback" not in r.stderr
    assert not list(tmp_path.iterdir())
    assert all(e[0] != "I" for e in log)  # no input recipe: nothing could have been sent
