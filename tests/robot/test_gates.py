"""Each gate on its own: what fires it, what it does to the command, what it says."""

from __future__ import annotations

import time

import numpy as np
import pytest

from mimicrete import _native
from mimicrete.robot import RobotState
from mimicrete.robot.gates import Gates, Limits, StartRefused, Stop

from .conftest import home_q


def limits(**kw) -> Limits:
    spec = _native.task_spec("TileSuction")
    return Limits.from_spec(spec, 0.04, **kw)


def state(q, safety=1, t=0.0, read_at=None, connected=True) -> RobotState:
    return RobotState(np.asarray(q, np.float64), np.zeros(6), safety, 0, 0, t,
                      connected, time.monotonic() if read_at is None else read_at)  # fmt: skip


def test_start_near_home_in_normal_mode_passes_and_names_what_fails():
    g = Gates(limits())
    q = home_q()
    g.check_start(state(q + 0.49))
    with pytest.raises(StartRefused, match=r"joint 4 \(wrist 2\) is at -1\.021 rad, 0\.550 rad"):
        g.check_start(state(q + np.array([0, 0, 0, 0.1, 0.55, 0])))
    with pytest.raises(StartRefused, match=r"REDUCED \(2\), not NORMAL"):
        g.check_start(state(q, safety=2))
    with pytest.raises(StartRefused, match="not connected"):
        g.check_start(state(q, connected=False))
    # a joint a whole turn away is the same angle
    g.check_start(state(q + np.array([2 * np.pi, 0, 0, 0, 0, 0])))


def test_command_within_a_joint_step_passes_unchanged():
    g = Gates(limits())
    q = home_q()
    target = q + np.array([0.04, -0.04, 0.02, 0, 0.01, -0.03])
    cmd, fired = g.gate_command(q, target)
    assert fired == [] and np.allclose(cmd, target)


def test_joint_step_clamps_each_joint():
    g = Gates(limits())
    q = home_q()
    cmd, fired = g.gate_command(q, q + np.array([0.2, 0, -0.1, 0, 0, 0.01]))
    assert fired == ["joint_step"]
    assert np.allclose(cmd - q, [0.04, 0, -0.04, 0, 0, 0.01])
    assert g.counts == {"joint_step": 1}


def test_speed_cap_below_the_step():
    g = Gates(limits(speed_cap=0.5))  # 0.02 rad per 40 ms
    q = home_q()
    cmd, fired = g.gate_command(q, q + np.array([0.04, 0.01, 0, 0, 0, 0]))
    assert fired == ["speed"]
    assert np.allclose(cmd - q, [0.02, 0.01, 0, 0, 0, 0])
    with pytest.raises(ValueError, match="at most half the ur3's slowest rated joint speed"):
        limits(speed_cap=2.0)


def test_workspace_holds_the_arm_where_it_is():
    lim = limits()
    g = Gates(lim)
    q = home_q()
    assert lim.outside(lim.tcp_of(q)) is None
    # lower the TCP towards the table until the target leaves the box: the shoulder down
    q_low = q.copy()
    while lim.outside(lim.tcp_of(q_low)) is None:
        q_low[1] -= 0.01
    reason = lim.outside(lim.tcp_of(q_low))
    assert reason is not None and "TCP z" in reason and "below 0.005" in reason
    start = q_low + np.array([0, 0.02, 0, 0, 0, 0])
    cmd, fired = g.gate_command(start, q_low)
    assert fired == ["workspace"] and np.allclose(cmd, start)
    assert "beyond the reach limit" in lim.outside(np.array([0.0, 0.6, 0.5]))


def test_non_finite_target_holds():
    g = Gates(limits())
    q = home_q()
    cmd, fired = g.gate_command(q, q + np.array([np.nan, 0, 0, 0, 0, 0]))
    assert fired == ["non_finite"] and np.allclose(cmd, q)


def test_state_checks_stop_with_their_reason():
    lim = limits()
    q = home_q()
    g = Gates(lim)
    g.check_state(state(q, t=1.0, read_at=10.0))
    g.check_state(state(q + 0.1, t=1.04, read_at=10.04))  # 0.1 rad in a tick: a fast move, no jump
    with pytest.raises(Stop, match=r"joint jump: joint 0 \(base\) moved 0\.130 rad") as e:
        g.check_state(state(q + np.array([0.23, 0.1, 0.1, 0.1, 0.1, 0.1]), t=1.08, read_at=10.08))
    assert e.value.kind == "joint_jump"
    g = Gates(lim)
    g.check_state(state(q, t=1.0, read_at=10.0))
    g.check_state(state(q, t=1.0, read_at=10.07))  # the same robot time 70 ms later: not yet
    with pytest.raises(Stop, match="stream stalled: no new state from the controller for 90 ms"):
        g.check_state(state(q, t=1.0, read_at=10.09))
    with pytest.raises(Stop, match=r"safety mode changed to ROBOT_EMERGENCY_STOP \(7\)"):
        Gates(lim).check_state(state(q, safety=7))
    with pytest.raises(Stop, match="connection lost"):
        Gates(lim).check_state(state(q, connected=False))
