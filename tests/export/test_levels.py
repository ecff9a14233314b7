"""The effector command exported as a level (issue 44 §1): every task the export supports writes
it as the commanded state held until the next command, and every exported episode, stepped
through the simulator from its seed (the level mapped to the env's command as a policy's would
be), gives back its demo step for step and ends as the demo did."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from mimicrete import _native, demos, tasks
from mimicrete.cli import main as cli_main
from mimicrete.export import ExportError, levels, source

from ._levels import expected_actions

#: scripted demos per task (rows are long: 3 tiles each)
TASK_DEMOS = {"suction": 3, "grip": 3, "screw": 3, "row": 2, "place": 3}
SUCTION_TASKS = ("suction", "row", "place")


@pytest.fixture(scope="module")
def task_demos(tmp_path_factory):
    """task -> a folder of its scripted demos (real hand logs through the real converter)."""
    from mimicrete import demonstrator as synth
    from mimicrete.teleop import convert

    made: dict[str, Path] = {}

    def get(task: str) -> Path:
        if task not in made:
            root = tmp_path_factory.mktemp(f"levels-{task}")
            out = root / "demos"
            out.mkdir()
            for i, p in enumerate(synth.synth_hands(task, TASK_DEMOS[task], 3, root / "hands")):
                convert.convert_log(p, task, out, episode_index=i)
            made[task] = out
        return made[task]

    return get


# ----------------------------------------------------------------------------- the conversion


def test_a_suction_switch_is_held_until_the_next():
    a = np.zeros((10, 7), np.float32)
    a[:, 0] = np.arange(10)  # the joint motions pass through
    a[:, 6] = [0, 0, 1, 0, 0.3, -1, 0, -1, 1, 0]  # 0.3 keeps, as the simulator reads it
    got = levels.to_levels("suction", a)
    assert got[:, 6].tolist() == [-1, -1, 1, 1, 1, -1, -1, -1, 1, 1]
    np.testing.assert_array_equal(got[:, :6], a[:, :6])
    assert a[0, 6] == 0  # the input is not changed
    for task in ("row", "place"):
        np.testing.assert_array_equal(levels.to_levels(task, a), got)
    assert levels.to_levels("suction", np.zeros((3, 7)))[:, 6].tolist() == [-1, -1, -1]
    assert levels.to_levels("suction", np.zeros((0, 7))).shape == (0, 7)


def test_a_gripper_keeps_its_commands_and_starts_open():
    a = np.zeros((9, 8), np.float32)
    a[:, 6] = [0, 0, -1, -1, 1, 1, 0, 0, -1]  # a later 0 stops the fingers: it stays
    a[:, 7] = [0, 0, 0, 1, 1, 0, 0, -1, 0]  # the screw's spin goes as recorded
    for task in ("grip", "screw"):
        got = levels.to_levels(task, a)
        assert got[:, 6].tolist() == [-1, -1, -1, -1, 1, 1, 0, 0, -1]
        np.testing.assert_array_equal(got[:, 7], a[:, 7])
    with pytest.raises(ValueError, match="no effector level"):
        levels.to_levels("juggle", a)
    with pytest.raises(ValueError, match="no effector column"):
        levels.to_levels("suction", np.zeros((4, 3)))


def test_to_env_gives_a_suction_level_its_sign():
    names = source.ACTION_NAMES["suction"]
    a = np.zeros((5, 7), np.float32)
    a[:, 0] = 0.25
    a[:, 6] = [0.2, -0.01, 0.0, 1.0, -3.0]
    got = levels.to_env(a, names)
    assert got[:, 6].tolist() == [1, -1, -1, 1, -1]
    assert got[:, 0].tolist() == [0.25] * 5
    np.testing.assert_array_equal(levels.to_env(a[0], names), got[0])  # one action
    grip = np.full((2, 7), 0.3, np.float32)
    np.testing.assert_array_equal(levels.to_env(grip, source.ACTION_NAMES["grip"]), grip)
    old = [*names[:6], "suction_command"]
    np.testing.assert_array_equal(levels.to_env(a, old), a)  # the old layout: as it was
    with pytest.raises(ValueError, match="width 7, 8 names"):
        levels.to_env(a, source.ACTION_NAMES["screw"])


def test_layout_of_names():
    for task in tasks.TASKS:
        assert levels.layout_of(source.ACTION_NAMES[task]) == "level", task
    assert levels.layout_of(["dq0", "gripper_command", "spin_command"]) == "switch"
    assert levels.layout_of(["dq0", "suction_command"]) == "switch"
    with pytest.raises(ValueError, match="no effector column"):
        levels.layout_of(["dq0", "dq1"])
    assert "suction_command" in levels.old_layout_message("x")


# ------------------------------------------------------------------- every task, exported


def _read_lerobot(root: Path) -> dict:
    info = json.loads((root / "meta/info.json").read_text())
    data = pq.read_table(sorted((root / "data").rglob("*.parquet"))[0])
    eps = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()

    def col(name):
        return np.stack(data.column(name).to_pylist()).astype(np.float32)

    return {
        "info": info,
        "state": col("observation.state"),
        "action": col("action"),
        "reward": data.column("next.reward").to_numpy(),
        "episode": data.column("episode_index").to_numpy(),
        "success": data.column("next.success").to_numpy(zero_copy_only=False),
        "episodes": eps,
    }


def _step_through(sim: str, seed: int, actions: np.ndarray) -> dict:
    """A fresh simulator from ``seed`` stepped through ``actions`` (stops where it ends)."""
    env = _native.SimEnv(sim)
    obs = [np.asarray(env.reset(seed), np.float32)]
    rewards, installed, ended_at = [], False, None
    for k, a in enumerate(actions):
        o, r, te, tr, info = env.step(np.asarray(a, np.float32))
        obs.append(np.asarray(o, np.float32))
        rewards.append(np.float32(r))
        installed = bool(info["installed"])
        if te or tr:
            ended_at = k
            break
    return {"obs": np.stack(obs), "rewards": np.array(rewards), "installed": installed,
            "ended_at": ended_at}  # fmt: skip


@pytest.mark.parametrize("task", list(TASK_DEMOS))
def test_every_exported_episode_replays_to_its_demos_outcome(task, task_demos, tmp_path):
    src = task_demos(task)
    d = demos.load(src)
    spec = tasks.get(task)
    out = tmp_path / "lr"
    assert cli_main(["export", str(src), "--format", "lerobot", "--out", str(out)]) == 0
    got = _read_lerobot(out)

    names = got["info"]["features"]["action"]["names"]
    assert names == source.ACTION_NAMES[task] and names[6].endswith("_level")
    frame = source.FRAME_NAMES[task]
    assert len(frame) == spec.obs_frame_dim == {"place": 32}.get(task, len(frame))
    assert got["state"].shape == (len(d), spec.obs_dim) == (len(d), 5 * len(frame))
    np.testing.assert_array_equal(got["state"], d.obs)
    # the exported action: the demo's, its effector command a level (computed step by step here)
    np.testing.assert_array_equal(got["action"], expected_actions(d, task))
    level = got["action"][:, 6]
    assert set(np.unique(level).tolist()) == {-1.0, 1.0}  # the scripted demos never stop a gripper
    recorded = d.actions[:, 6]
    if task in SUCTION_TASKS:
        # a switch is a 0.2-0.5 % of the frames; the level is set on every one
        assert np.count_nonzero(recorded) / len(d) < 0.01
        for s in d.episode_slices():
            changes = np.flatnonzero(np.diff(level[s])) + 1
            switches = np.flatnonzero(recorded[s])
            assert level[s][0] == -1 and set(changes) <= set(switches), s
            assert len(changes) >= 1  # switched on at least once
            on = switches[recorded[s][switches] > 0]
            assert (level[s][on] == 1).all()

    rng = np.random.default_rng(0)
    slices = d.episode_slices()
    assert any(e["mimicrete/success"] for e in got["episodes"])
    assert [e["length"] for e in got["episodes"]] == [s.stop - s.start for s in slices]
    for ep, s, meta in zip(got["episodes"], slices, d.metas, strict=True):
        assert ep["mimicrete/seed"] == int(meta["seed"])
        assert ep["mimicrete/success"] == (meta["success"] == "true")
        act = got["action"][s].copy()
        if task in SUCTION_TASKS:  # a policy's level: any size, only its sign says on or off
            act[:, 6] *= rng.uniform(0.01, 1.0, size=len(act)).astype(np.float32)
        run = _step_through(spec.sim, ep["mimicrete/seed"], levels.to_env(act, names))
        n = s.stop - s.start
        assert run["ended_at"] == (n - 1 if d.terminated[s.stop - 1] else None), ep
        np.testing.assert_array_equal(run["obs"][:n], got["state"][s])
        np.testing.assert_array_equal(run["rewards"], got["reward"][s])
        assert run["installed"] == bool(got["success"][s.stop - 1]) == ep["mimicrete/success"]
        if task in SUCTION_TASKS:
            # the demo's switch column taken for a level (0 -> off) lets go right after the pick:
            # the mapping back is what makes the replay the demo's
            spikes = levels.to_env(d.actions[s], names)
            wrong = _step_through(spec.sim, ep["mimicrete/seed"], spikes)
            m = min(len(wrong["obs"]), n)
            assert not np.array_equal(wrong["obs"][:m], got["state"][s][:m])
            assert not wrong["installed"]


@pytest.mark.parametrize("task", ["place", "grip"])
def test_minari_levels_step_the_gym_env(task, task_demos, tmp_path, monkeypatch):
    """Minari's recovered env (gymnasium) stepped with the dataset's actions as they are."""
    import minari

    src = task_demos(task)
    d = demos.load(src)
    out = tmp_path / "mn"
    assert cli_main(["export", str(src), "--format", "minari", "--out", str(out)]) == 0
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(out))
    ds = minari.load_dataset(f"mimicrete/{tasks.get(task).sim}/demos-v0")
    assert ds.storage.metadata["mimicrete_action_layout"] == "level"
    assert ds.storage.metadata["mimicrete_action_names"] == source.ACTION_NAMES[task]
    env = ds.recover_environment()
    want = expected_actions(d, task)
    episodes = list(ds.iterate_episodes())
    metas = list(ds.storage.get_episode_metadata(range(len(episodes))))
    for ep, s, meta in zip(episodes, d.episode_slices(), metas, strict=True):
        np.testing.assert_array_equal(ep.actions, want[s])
        obs, _ = env.reset(options=meta["options"])
        np.testing.assert_array_equal(obs, ep.observations[0])
        for k, a in enumerate(ep.actions):
            obs, r, term, trunc, info = env.step(a)
            np.testing.assert_array_equal(obs, ep.observations[k + 1])
            assert r == ep.rewards[k]
        assert bool(info["installed"]) == meta["success"]


def test_a_level_that_does_not_replay_is_refused(demos3, monkeypatch):
    """Should the simulator stop latching the suction, the level would not give the demo back:
    the export says so (the recorded actions still replay), naming the file."""
    real = levels.to_env

    def unlatched(actions, names):  # the suction off on the steps the demo only kept it on
        a = real(actions, names)
        a[1:, 6] = np.where(np.diff(a[:, 6]) != 0, a[1:, 6], -1.0)
        return a

    monkeypatch.setattr(levels, "to_env", unlatched)
    with pytest.raises(ExportError) as e:
        source.read_demo_dir(demos3)
    msg = str(e.value)
    assert msg.startswith(str(sorted(demos3.glob("*.mcap"))[0]))
    assert "its recorded actions replay, its effector command as a level does not" in msg
    assert "gives another observation at step" in msg and os.linesep not in msg
