"""deploy's observation (joint angles + tile pose -> tile-sim's TileSuction frame, stacked) is the
simulator's own along a policy's episode, and the sim backend runs the policy to an install."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mimicrete import _native
from mimicrete.learn.run_files import load_policy
from mimicrete.robot import deploy as dep
from mimicrete.robot.gates import Limits
from mimicrete.robot.observe import ObservationError, Observer
from mimicrete.robot.sim import SimRobot
from mimicrete.robot.tile_pose import FixedTilePose

from .conftest import TILE


@pytest.fixture(scope="module")
def policy(run_dir):
    actor, _ = load_policy(run_dir)
    return dep.torch_policy(actor)


@pytest.mark.parametrize("tile", [TILE, (0.2, 0.3, 0.4)])
def test_observation_equals_the_simulators_along_an_episode(policy, tile):
    env = _native.SimEnv("TileSuction", 0)
    obs = env.reset(0, object_pose=list(tile), target_offset=[0.0, 0.0])
    snap = env.snapshot()
    ob = Observer(env.spec(), np.asarray(snap["target"]["t"]))
    suction = False
    held_steps = 0
    for step in range(300):
        q = np.asarray(snap["q"], np.float64)
        o = snap["object"]["t"]
        # the tile from a source that tracks it (the simulator's own pose), yaw unused
        tile_xyz, how = ob.tile_centre(ob.tool0(q), suction, (o[0], o[1], 0.0), step)
        if how == "held":
            held_steps += 1
            # carried with the cups as the simulator carries it
            assert np.allclose(tile_xyz, o, atol=2e-3), (step, tile_xyz, o)
        else:
            assert np.allclose(tile_xyz[:2], o[:2]) and abs(tile_xyz[2] - o[2]) < 2e-3
        mine = ob.push(q, suction, np.asarray(o), ob.tool0(q))
        assert mine.shape == obs.shape
        assert np.allclose(mine, obs, atol=2e-5), (step, np.abs(mine - obs).max())
        a = policy(obs)
        suction = True if a[6] >= 0.5 else False if a[6] <= -0.5 else suction
        obs, _, terminated, truncated, info = env.step(a.astype(np.float32))
        snap = env.snapshot()
        if terminated or truncated:
            break
    assert info["installed"]  # the policy did its job in that episode
    assert held_steps > 10  # and the held tile was tracked for a good part of it


def test_sim_backend_installs_through_the_deploy_loop(policy, tmp_path):
    tile = TILE
    task = dep.Task.of_run("TileSuction-v0", None, tile)
    robot = SimRobot(task="TileSuction", tile_pose=tile)

    class SimTile:  # the simulator's own tile
        label = "sim"
        version = 0

        def pose(self):
            return robot.tile_pose()

        def close(self):
            pass

    limits = Limits.from_spec(task.spec, task.joint_step)
    o = dep.run(robot, policy, task, SimTile(), tmp_path / "sim.mcap", limits=limits,
                ticks=400, realtime=False)  # fmt: skip
    assert o.kind == "episode" and o.reason.endswith("installed"), o
    s = dep.summary(o.path)
    assert s["ticks"] == o.ticks and s["sent"] == o.ticks
    assert s["tile_sources"].get("held", 0) > 10
    # the log's commands replayed in a fresh simulator do what the sim backend did, exactly
    from mimicrete.robot.replay import replay

    r = replay(o.path)
    assert r["replayed"] == o.ticks and r["ended"] == "installed" and r["installed"]
    assert r["sim_to_command_rad"]["max"] < 1e-9
    assert r["read_to_sim_rad"]["max"] < 1e-9
    assert Path(r["replay"]).name == "sim_replay.mcap" and Path(r["replay"]).is_file()


def test_other_tasks_are_refused():
    spec = _native.task_spec("BlockGrip")
    with pytest.raises(ObservationError, match="TileSuction-layout"):
        Observer(spec, np.zeros(3))
    place = _native.task_spec("TilePlace")
    with pytest.raises(ObservationError, match="TilePlace"):
        Observer(place, np.zeros(3))
    # a suction task whose actions move the tool, not the joints
    tool = _native.task_spec("TileSuction")
    tool["robot"] = {**tool["robot"], "action": "tool"}
    with pytest.raises(ObservationError, match=r"moves the tool \(robot.action = 'tool'\)"):
        Observer(tool, np.zeros(3))


def test_a_robot_interface_that_raises_stops_the_run_with_a_valid_log(policy, tmp_path):
    """ur-rtde raises RuntimeError when a call fails (a controller gone mid-command): the run
    stops with the robot's message and the log is finished."""
    task = dep.Task.of_run("TileSuction-v0", None, TILE)

    class Failing(SimRobot):
        sent = 0

        def send_joint_target(self, q, suction):
            self.sent += 1
            if self.sent == 6:
                raise RuntimeError("RTDE control script is not running")
            super().send_joint_target(q, suction)

    robot = Failing(task="TileSuction", tile_pose=TILE)
    limits = Limits.from_spec(task.spec, task.joint_step)
    o = dep.run(robot, policy, task, FixedTilePose(*TILE), tmp_path / "f.mcap", limits=limits,
                ticks=50, realtime=False)  # fmt: skip
    assert o.kind == "robot" and o.ticks == 5
    assert o.reason == "robot error while commanding: RTDE control script is not running"
    assert robot.stopped == o.reason
    s = dep.summary(o.path)
    assert s["ticks"] == 5 and s["stop_kind"] == "robot"
