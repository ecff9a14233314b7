"""The shadow backend through the real CLI and the library: the group 3 policy reads a loopback
controller through ur-rtde's real receive interface, computes every command, sends nothing, and
logs each tick; scripted faults each stop the run with their reason and a valid log."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import mimicrete
from mimicrete import demos
from mimicrete.learn.run_files import load_policy
from mimicrete.robot import deploy as dep
from mimicrete.robot.gates import Limits
from mimicrete.robot.rtde import ShadowRobot
from mimicrete.robot.tile_pose import FixedTilePose

from ._rtde_server import LoopbackRobot
from .conftest import TILE, home_q, tcp_of

sys.path.insert(0, str(Path(__file__).parent.parent))
from _cli_run import run_cli  # noqa: E402

TILE_ARG = "fixed:{},{},{}".format(*TILE)


def _ticks(path: Path) -> list[dict]:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(["/deploy/tick"])]


def _check_log(path: Path) -> dict:
    """The log is a finished, intact demo; its deploy summary."""
    rep = demos.verify(path)
    assert rep["ok"], rep["problems"]
    info = demos.inspect(path)
    assert info["finished"]
    s = dep.summary(path)
    assert s is not None and s["ticks"] == info["steps"]
    return s


def test_shadow_runs_the_policy_for_200_ticks_through_the_cli(run_dir, controller, tmp_path):
    out = tmp_path / "logs"
    r = run_cli(
        "deploy", str(run_dir), "--robot", "ur3", "--shadow", "--host", controller.host,
        "--tile-pose", TILE_ARG, "--ticks", "200", "--out", str(out),
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "shadow: 200 ticks" in r.stdout
    (path,) = out.glob("deploy_shadow_*.mcap")
    s = _check_log(path)
    assert s["ticks"] == 200 and s["sent"] == 0  # every command computed, none sent
    assert s["stop_reason"] == "ran the 200 ticks asked for"
    assert s["tile_sources"] == {"fixed": 200}  # the arm never moves: the tile is never reached
    lat = s["latency_ms"]
    assert 0 < lat["p50"] <= lat["p99"] < 80  # within the deadline of 2 control periods
    ticks = _ticks(path)
    q0 = home_q()
    for k, t in enumerate(ticks):
        assert t["step"] == k and t["sent"] is False and t["safety_mode"] == 1
        assert np.allclose(t["q_read"], q0)
        assert np.allclose(t["tile_pose"], TILE)
        # the gated command is within one joint step of what was read
        assert np.all(np.abs(np.subtract(t["command_q"], t["q_read"])) <= 0.04 + 1e-9)
    # the policy is live, not a constant: its commands move the arm towards the tile
    assert any(np.abs(np.subtract(t["command_q"], q0)).max() > 0.01 for t in ticks)
    # the demo channel holds the observation the policy saw: frames of q, suction, tcp, target,
    # tile; the newest frame's tile is the fixed pose on the table
    d = demos.load(path)
    assert d["obs"].shape == (200, 80)
    assert np.allclose(d["obs"][:, -3:], [TILE[0], TILE[1], 0.005], atol=1e-6)
    assert np.allclose(d["obs"][:, 64:70], q0, atol=1e-6)
    # the controller was only read: no input recipe was ever set up
    kinds = [e[0] for e in controller.log()["log"]]
    assert "I" not in kinds and kinds.count("S") == 1
    # inspect prints the gate counts and the latency percentiles
    r = run_cli("inspect", str(path))
    assert r.returncode == 0, r.stderr
    assert "deploy: 200 ticks, 0 commands sent" in r.stdout
    assert "read -> command latency (ms): p50" in r.stdout
    print(r.stdout[r.stdout.index("deploy:") :])
    # the commands replayed in the simulator: each is reached (one joint step from the arm the
    # shadow read, which never moved), nothing picked
    r = run_cli("deploy", "--replay", str(path), "--out", str(tmp_path / "replay.mcap"))
    assert r.returncode == 0, r.stderr
    assert "replayed 200 of 200 ticks" in r.stdout
    assert "simulated arm to the command, largest joint: median 0.0000 rad" in r.stdout
    assert "picked False" in r.stdout
    assert demos.verify(tmp_path / "replay.mcap")["ok"]


# --- faults --------------------------------------------------------------------------------------

FAULT_AT = 15


@pytest.fixture(scope="module")
def policy_and_task(run_dir):
    actor, cfg = load_policy(run_dir)
    task = dep.Task.of_run(cfg.env_settings.env_id, None, TILE)
    pol = dep.torch_policy(actor)
    pol(np.zeros(80, np.float32))
    return pol, task


def _run(controller, policy, task, tmp_path, on_tick, ticks=60):
    robot = ShadowRobot(controller.host)
    time.sleep(0.05)
    limits = Limits.from_spec(task.spec, task.joint_step)
    out = tmp_path / "fault.mcap"
    o = dep.run(
        robot, policy, task, FixedTilePose(*TILE), out, limits=limits, ticks=ticks, on_tick=on_tick
    )
    return o


FAULTS = {
    "protective_stop": (lambda c: c.set(safety_mode=3), "safety_mode", "PROTECTIVE_STOP (3)"),
    "safeguard_stop": (lambda c: c.set(safety_mode=5), "safety_mode", "SAFEGUARD_STOP (5)"),
    "joint_jump": (
        lambda c: c.set(q=home_q() + np.array([0, 0, 0.3, 0, 0, 0])),
        "joint_jump",
        "joint 2 (elbow) moved 0.300 rad",
    ),
    "stalled_stream": (lambda c: c.set(stall=True), "stalled", "stream stalled"),
    "dropped_socket": (lambda c: c.drop(), "connection", "connection lost"),
}


@pytest.mark.parametrize("fault", list(FAULTS))
def test_each_fault_stops_the_run_with_its_reason_and_a_valid_log(
    fault, controller, policy_and_task, tmp_path
):
    inject, kind, words = FAULTS[fault]
    policy, task = policy_and_task

    def on_tick(step: int) -> None:
        if step == FAULT_AT:
            inject(controller)

    o = _run(controller, policy, task, tmp_path, on_tick)
    assert o.kind == kind, o.reason
    assert words in o.reason
    # stopped within a few ticks of the fault (a stall: after the 80 ms deadline)
    assert FAULT_AT <= o.ticks <= FAULT_AT + 4, o
    s = _check_log(o.path)
    assert s["stop_kind"] == kind and s["stop_reason"] == o.reason
    assert s["ticks"] == o.ticks


def test_a_policy_exception_stops_the_run(controller, policy_and_task, tmp_path):
    policy, task = policy_and_task
    calls = []

    def broken(obs):
        calls.append(1)
        if len(calls) > 10:
            raise RuntimeError("the GPU fell off")
        return policy(obs)

    robot = ShadowRobot(controller.host)
    time.sleep(0.05)
    limits = Limits.from_spec(task.spec, task.joint_step)
    o = dep.run(
        robot, broken, task, FixedTilePose(*TILE), tmp_path / "p.mcap", limits=limits, ticks=50
    )
    assert o.kind == "policy" and "RuntimeError: the GPU fell off" in o.reason
    assert o.ticks == 10
    assert _check_log(o.path)["stop_kind"] == "policy"


def test_a_slow_policy_misses_the_deadline(controller, policy_and_task, tmp_path):
    policy, task = policy_and_task
    calls = []

    def slow(obs):
        calls.append(1)
        if len(calls) == 8:
            time.sleep(0.12)  # 3 control periods
        return policy(obs)

    robot = ShadowRobot(controller.host)
    time.sleep(0.05)
    limits = Limits.from_spec(task.spec, task.joint_step)
    o = dep.run(
        robot, slow, task, FixedTilePose(*TILE), tmp_path / "d.mcap", limits=limits, ticks=50
    )
    assert o.kind == "deadline", o.reason
    assert o.ticks == 8  # the late command is logged, then the run stops
    assert _check_log(o.path)["latency_ms"]["max"] > 80


# --- through the real CLI: refused starts, signals -----------------------------------------------


def _deploy(run_dir, host, *extra):
    return run_cli(
        "deploy",
        str(run_dir),
        "--robot",
        "ur3",
        "--shadow",
        "--host",
        host,
        "--tile-pose",
        TILE_ARG,
        *extra,
    )


def test_start_refused_away_from_home(run_dir, tmp_path):
    q = home_q() + np.array([0, 0.6, 0, 0, 0, 0])
    with LoopbackRobot(q, tcp=tcp_of(q)) as c:
        r = _deploy(run_dir, c.host, "--out", str(tmp_path))
    assert r.returncode == 2
    assert (
        "start refused: joint 1 (shoulder) is at -1.230 rad, 0.600 rad from the spec's "
        "home_q -1.830" in r.stderr
    )
    assert "Traceback" not in r.stderr
    assert not list(tmp_path.glob("*.mcap*"))  # nothing written before the start passes


def test_start_refused_in_a_protective_stop(run_dir, tmp_path):
    q = home_q()
    with LoopbackRobot(q, tcp=tcp_of(q), safety_mode=3) as c:
        r = _deploy(run_dir, c.host, "--out", str(tmp_path))
    assert r.returncode == 2
    assert "start refused: safety mode is PROTECTIVE_STOP (3), not NORMAL" in r.stderr


def test_a_controller_that_sends_no_data_is_refused(run_dir, tmp_path):
    q = home_q()
    with LoopbackRobot(q, tcp=tcp_of(q), stall=True) as c:
        r = _deploy(run_dir, c.host, "--out", str(tmp_path))
    assert r.returncode == 2
    assert f"--host {c.host}: connected, but no data from the controller within 2 s" in r.stderr
    assert not list(tmp_path.glob("*.mcap*"))


def test_no_controller_at_the_host(run_dir, tmp_path):
    r = _deploy(run_dir, "127.254.254.254", "--out", str(tmp_path))
    assert r.returncode == 2
    assert "--host 127.254.254.254: cannot read the controller" in r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--robot", "ur5e", "--shadow", "--host", "1.2.3.4", "--tile-pose", TILE_ARG],
            "--robot ur5e: RUN was trained on a ur3 (TileSuction)",
        ),
        (["--robot", "ur3", "--shadow", "--tile-pose", TILE_ARG], "--shadow needs --host IP"),
        (["--robot", "ur3", "--shadow", "--host", "1.2.3.4"], "--shadow needs --tile-pose"),
        (
            ["--robot", "ur3", "--sim", "--tile-pose", "fixed:0.1,0.3"],
            "fixed:X,Y,YAW takes three numbers",
        ),
        (
            ["--robot", "ur3", "--sim", "--tile-pose", "fixed:0.9,0.3,0"],
            "puts the object off the table",
        ),
        (
            ["--robot", "ur3", "--sim", "--tile-pose", "file:/no/such/file"],
            "--tile-pose file:/no/such/file: No such file or directory",
        ),
        (["--robot", "ur3", "--sim", "--speed-cap", "5"], "--speed-cap: 5.0 rad/s"),
        (["--robot", "ur9", "--sim"], "--robot ur9: one of ur3, ur3e"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(run_dir, args, message):
    r = run_cli("deploy", str(run_dir), *args)
    assert r.returncode == 2, r.stdout + r.stderr
    assert message.replace("RUN", str(run_dir)) in r.stderr
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_bad_tile_pose_file_line_stops_with_its_line(run_dir, tmp_path):
    poses = tmp_path / "tile.jsonl"
    poses.write_text('{"x": 0.1, "y": 0.32, "yaw": 0.0}\n')
    q = home_q()
    with LoopbackRobot(q, tcp=tcp_of(q)) as c:
        proc = _popen_deploy(run_dir, c.host, tmp_path, f"file:{poses}")
        _wait_for_ticks(tmp_path, proc)
        with open(poses, "a") as f:
            f.write('{"x": 0.1, "y": "near", "yaw": 0.0}\n')
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 1, err
    assert f"tile pose: {poses}:2: field 'y' must be a finite number, got 'near'" in err
    (path,) = tmp_path.glob("deploy_shadow_*.mcap")
    assert _check_log(path)["stop_kind"] == "tile_pose"


def _popen_deploy(run_dir, host, out, tile=TILE_ARG):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(Path(mimicrete.__file__).parent.parent)
    return subprocess.Popen(
        [sys.executable, "-m", "mimicrete", "deploy", str(run_dir), "--robot", "ur3", "--shadow",
         "--host", host, "--tile-pose", tile, "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )  # fmt: skip


def _wait_for_ticks(out: Path, proc, timeout: float = 60.0) -> None:
    """Until the run's partial log holds a few ticks (its first chunk is on disk)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if any(p.stat().st_size > 0 for p in out.glob("*.mcap.partial")):
            time.sleep(0.5)  # ~12 ticks
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise TimeoutError("the deploy run wrote no log")


@pytest.mark.parametrize(
    ("sig", "reason"),
    [(signal.SIGTERM, "SIGTERM received"), (signal.SIGINT, "interrupted (Ctrl-C)")],
)
def test_sigterm_and_ctrl_c_stop_cleanly_with_a_valid_log(run_dir, tmp_path, sig, reason):
    q = home_q()
    with LoopbackRobot(q, tcp=tcp_of(q)) as c:
        proc = _popen_deploy(run_dir, c.host, tmp_path)
        _wait_for_ticks(tmp_path, proc)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert f"stopped: {reason}" in out and "Traceback" not in err
    (path,) = tmp_path.glob("deploy_shadow_*.mcap")
    s = _check_log(path)
    assert s["stop_kind"] == "signal" and s["stop_reason"] == reason and s["ticks"] > 5
