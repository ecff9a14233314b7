"""A researcher's task spec file from Python (issue 26 §1): ``gym.make("mimicrete/Task-v0",
spec=PATH)`` and its vector env run the file (an unchanged copy of a built-in spec gives the
built-in env's episodes bit for bit; a bigger tile gives other observations), the task table reads
the built-in specs, and ``mimicrete synth-hands --task-file`` plans from the file or refuses a bad
one in one line (file, field, value, why), exit 2, through the real command line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from mimicrete import _native, envs, tasks

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _cli_run import run_cli  # noqa: E402

TILE = "half_extents = [0.075, 0.075, 0.005]"
BIG_TILE = "half_extents = [0.1, 0.1, 0.006]"
#: a 0.2 m tile turned 30 degrees at the built-in wide box's near edge would touch the pad: the
#: spec check refuses it, so the bigger tile's wide starts begin 3.5 cm further out
BIG_WIDE = ("object_x = [0.035, 0.285]", "object_x = [0.07, 0.285]")


def spec_copy(tmp_path: Path, task: str = "TileSuction", *edits: tuple[str, str]) -> Path:
    text = _native.task_spec(task, as_toml=True)
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / f"{task.lower()}_{len(list(tmp_path.iterdir()))}.toml"
    path.write_text(text)
    return path


def actions(n: int, act_dim: int, seed: int, batch: int | None = None) -> np.ndarray:
    shape = (n, act_dim) if batch is None else (n, batch, act_dim)
    return np.random.default_rng(seed).uniform(-1, 1, size=shape).astype(np.float32)


def run_episode(env: gym.Env, seed: int, acts: np.ndarray) -> list:
    obs, info = env.reset(seed=seed)
    out = [(obs, info["episode_seed"], info["start"])]
    for a in acts:
        obs, r, term, trunc, info = env.step(a)
        out.append((obs, r, term, trunc, info))
        if term or trunc:
            break
    return out


def assert_same(a: object, b: object) -> None:
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and np.array_equal(a, b)
    elif isinstance(a, (list, tuple)):
        assert isinstance(b, (list, tuple)) and len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            assert_same(x, y)
    elif isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys()
        for k in a:
            assert_same(a[k], b[k])
    else:
        assert a == b


@pytest.mark.parametrize("task", ["TileSuction", "BlockGrip", "Screw", "TileRow"])
def test_an_unchanged_copy_gives_the_builtin_episodes_bit_for_bit(tmp_path: Path, task) -> None:
    path = spec_copy(tmp_path, task)
    mine = gym.make("mimicrete/Task-v0", spec=str(path))
    builtin = gym.make(f"mimicrete/{task}-v0")
    assert mine.unwrapped.task == task and mine.unwrapped.task_file == str(path)
    assert mine.observation_space == builtin.observation_space
    assert mine.action_space == builtin.action_space
    assert mine.unwrapped.task_spec == _native.task_spec(task)
    acts = actions(150, builtin.action_space.shape[0], seed=5)
    for seed in (0, 11):
        a, b = run_episode(mine, seed, acts), run_episode(builtin, seed, acts)
        assert len(a) > 1
        assert_same(a, b)


def test_a_bigger_tile_gives_other_observations(tmp_path: Path) -> None:
    big = spec_copy(tmp_path, "TileSuction", (TILE, BIG_TILE), BIG_WIDE)
    mine = gym.make("mimicrete/Task-v0", spec=big)  # a Path is accepted too
    builtin = gym.make("mimicrete/TileSuction-v0")
    assert mine.unwrapped.task_spec["object"]["half_extents"] == [0.1, 0.1, 0.006]
    (o1, _), (o0, _) = mine.reset(seed=3), builtin.reset(seed=3)
    frame = tasks.get("suction").obs_frame_dim
    # the newest frame's tile centre [13:16] and target [10:13]: z is half a thickness up, 6 mm
    # instead of 5 (on the table; on the pad 0.04 m up); x, y are the same start
    new1, new0 = o1[-frame:], o0[-frame:]
    assert new0[15] == pytest.approx(0.005, abs=1e-6) and new1[15] == pytest.approx(0.006, abs=1e-6)
    assert new1[12] - new0[12] == pytest.approx(0.001, abs=1e-6)
    np.testing.assert_array_equal(new1[13:15], new0[13:15])
    acts = actions(60, 7, seed=2)
    a, b = run_episode(mine, 3, acts), run_episode(builtin, 3, acts)
    assert not np.array_equal(a[-1][0], b[-1][0])


def test_spaces_come_from_the_env_the_spec_builds(tmp_path: Path) -> None:
    # a Screw spec (tile-sim picks Screw's logic from the gripper's spin rate): 18-dim frames and
    # a spin command, whatever the file's name
    path = spec_copy(tmp_path, "Screw", ('name = "Screw"', 'name = "MyNut"'))
    env = gym.make("mimicrete/Task-v0", spec=str(path))
    assert env.unwrapped.task == "Screw" and env.unwrapped.task_spec["name"] == "MyNut"
    assert env.observation_space.shape == (90,) and env.action_space.shape == (8,)
    vec = envs.make_vec("Task-v0", 2, seed=0, spec=path)
    assert vec.single_action_space.shape == (8,) and vec.observation_space.shape == (2, 90)


def test_the_joint_step_is_the_files(tmp_path: Path) -> None:
    # robot.joint_step: a full action moves each joint by it (the built-in tasks' MAX_JOINT_STEP
    # unless a spec sets it), in the single and the vector env
    edit = ('model = "ur3"', 'model = "ur3"\njoint_step = 0.015')
    slow = spec_copy(tmp_path, "TileSuction", edit)
    assert tasks.load_task_file(slow)[1]["robot"]["joint_step"] == 0.015
    assert "joint_step" not in _native.task_spec("TileSuction")["robot"]
    builtin = gym.make("mimicrete/TileSuction-v0")
    assert builtin.unwrapped.joint_step == envs.MAX_JOINT_STEP == 0.04
    env = gym.make("mimicrete/Task-v0", spec=str(slow))
    assert env.unwrapped.joint_step == 0.015
    env.reset(seed=0)
    q0 = np.asarray(env.unwrapped.sim.snapshot()["q"])
    a = np.array([1, -1, 0.5, 0, -0.25, 2, 0], np.float32)
    env.step(a)
    q1 = np.asarray(env.unwrapped.sim.snapshot()["q"])
    want = np.clip(a[:6], -1, 1).astype(np.float64) * 0.015
    np.testing.assert_allclose(q1 - q0, want, atol=1e-12)
    assert envs.make_vec("Task-v0", 2, seed=0, spec=slow).joint_step == 0.015


def test_the_vector_env_runs_the_file(tmp_path: Path) -> None:
    copy = spec_copy(tmp_path, "TileSuction")
    mine = envs.make_vec("mimicrete/Task-v0", 3, seed=7, spec=str(copy))
    builtin = envs.make_vec("TileSuction-v0", 3, seed=7)
    assert mine.task == "TileSuction" and mine.task_spec == _native.task_spec("TileSuction")
    assert_same(mine.reset(seed=7), builtin.reset(seed=7))
    for a in actions(40, 7, seed=1, batch=3):
        assert_same(mine.step(a), builtin.step(a))
    # the episode length is the file's: 5 steps, then the same-step auto-reset
    short = spec_copy(tmp_path, "TileSuction", ("max_steps = 750", "max_steps = 5"))
    vec = gym.make_vec(
        "mimicrete/Task-v0", num_envs=2, vectorization_mode="vector_entry_point", spec=str(short)
    )
    assert isinstance(vec, envs.MimicreteVecEnv) and vec.task_spec["episode"]["max_steps"] == 5
    vec.reset(seed=0)
    flags = [vec.step(np.zeros((2, 7), np.float32))[3].tolist() for _ in range(5)]
    assert flags == [[False, False]] * 4 + [[True, True]]
    # state / restore rebuilds a spec env mid-episode
    big_tile = spec_copy(tmp_path, "TileSuction", (TILE, BIG_TILE), BIG_WIDE)
    big = envs.make_vec("Task-v0", 2, seed=4, spec=big_tile)
    big.reset(seed=4)
    for a in actions(7, 7, seed=3, batch=2):
        obs = big.step(a)[0]
    other = envs.make_vec("Task-v0", 2, seed=0, spec=big.task_file)
    np.testing.assert_array_equal(other.restore(big.state()), obs)


def test_the_task_file_id_refuses_what_is_not_a_spec(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="needs spec=PATH"):
        gym.make("mimicrete/Task-v0")
    with pytest.raises(ValueError, match="needs spec=PATH"):
        envs.make_vec("Task-v0", 2)
    with pytest.raises(ValueError, match="spec= goes with mimicrete/Task-v0"):
        envs.make_vec("TileSuction-v0", 2, spec=spec_copy(tmp_path))
    bad = spec_copy(tmp_path, "TileSuction", ("mass = 0.5 ", "mass = -2 "))
    for make in (lambda: gym.make("mimicrete/Task-v0", spec=str(bad)),
                 lambda: envs.make_vec("Task-v0", 2, spec=str(bad))):  # fmt: skip
        with pytest.raises(_native.SimInputError) as e:
            make()
        assert (e.value.field, e.value.value) == ("object.mass", "-2.0")
    with pytest.raises(FileNotFoundError):
        gym.make("mimicrete/Task-v0", spec=str(tmp_path / "missing.toml"))


def test_the_task_table_reads_the_builtin_specs() -> None:
    for t in tasks.TABLE.values():
        spec = t.builtin_spec()
        assert spec["name"] == t.sim
        assert t.max_steps == spec["episode"]["max_steps"]
        assert t.effector == spec["effector"]["kind"]
        sim = _native.SimEnv(t.sim, 0)
        assert (t.obs_dim, t.act_dim) == (sim.obs_dim, sim.act_dim)
        assert t.obs_frame_dim == sim.obs_frame_dim
    effectors = [t.effector for t in tasks.TABLE.values()]
    assert effectors == ["suction", "gripper", "gripper", "suction", "suction"]
    # the shared default, 750 steps, is the single-object tasks'; the row's is its own
    steps = [tasks.MAX_EPISODE_STEPS] * 3 + [2000, tasks.MAX_EPISODE_STEPS]
    assert [t.max_steps for t in tasks.TABLE.values()] == steps


# ----------------------------------------------------------------------------------------------
# mimicrete synth-hands --task-file, through the real command line
# ----------------------------------------------------------------------------------------------


def frames(path: Path) -> tuple[dict, list[str]]:
    lines = path.read_text().splitlines()
    return json.loads(lines[0]), lines[1:]


def test_synth_hands_plans_from_the_task_file(tmp_path: Path) -> None:
    copy = spec_copy(tmp_path, "TileSuction")
    big = spec_copy(tmp_path, "TileSuction", (TILE, BIG_TILE), BIG_WIDE)
    outs = {}
    for name, extra in [("builtin", []), ("copy", ["--task-file", str(copy)]),
                        ("big", ["--task-file", str(big)])]:  # fmt: skip
        outs[name] = tmp_path / name
        r = run_cli("synth-hands", *extra, "--episodes", "2", "--seed", "3",
                    "--out", str(outs[name]))  # fmt: skip
        assert r.returncode == 0, r.stderr
        assert "wrote 2 hand logs" in r.stdout
    for log in sorted(outs["builtin"].glob("*.jsonl")):
        h0, f0 = frames(log)
        h1, f1 = frames(outs["copy"] / log.name)
        h2, f2 = frames(outs["big"] / log.name)
        assert "task_file" not in h0["extra"]
        assert h1["extra"]["task_file"] == str(copy) and h1["task"] == "suction"
        assert h1["extra"]["task_spec"] == json.loads(json.dumps(_native.task_spec("TileSuction")))
        assert h1["extra"]["scene"] == h0["extra"]["scene"] and f1 == f0  # the same person
        assert h2["extra"]["task_spec"]["object"]["half_extents"] == [0.1, 0.1, 0.006]
        assert h2["extra"]["scene"]["object"][2] == pytest.approx(0.006, abs=1e-6)
        assert h2["extra"]["scene"]["target"][2] - h0["extra"]["scene"]["target"][2] == (
            pytest.approx(0.001, abs=1e-6)
        )
        assert f2 != f0  # the hand goes to the thicker tile
    converted_in_their_spec(tmp_path, outs, copy, big)


def first_scene(path: Path) -> dict[str, dict]:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        for _, _, message in make_reader(f).iter_messages(topics=["/scene"]):
            return {e["id"]: e for e in json.loads(message.data)["entities"]}
    raise AssertionError("no /scene")


def converted_in_their_spec(tmp_path: Path, outs: dict[str, Path], copy: Path, big: Path) -> None:
    """``mimicrete convert`` runs each log in the spec file its header names: an unchanged copy
    of the built-in spec gives the built-in demos' steps bit for bit, the bigger tile another
    episode whose demo draws and names that tile; a spec changed since, or gone, is one line
    per log, exit 2, and no demo."""
    from mimicrete import demos

    made = {}
    for name in outs:
        made[name] = tmp_path / f"demos_{name}"
        r = run_cli("convert", str(outs[name]), "--task", "suction", "--out", str(made[name]),
                    "--no-progress")  # fmt: skip
        assert r.returncode == 0, r.stderr
    for demo in sorted(made["builtin"].glob("*.mcap")):
        d0, d1, d2 = (demos.read(made[k] / demo.name) for k in ("builtin", "copy", "big"))
        for key in ("obs", "actions", "rewards", "terminated", "truncated"):
            assert np.array_equal(d0[key], d1[key]), key
        assert d1["meta"]["task_file"] == str(copy) and "task_file" not in d0["meta"]
        assert json.loads(d2["meta"]["task_spec"])["object"]["half_extents"] == [0.1, 0.1, 0.006]
        assert len(d2["obs"]) != len(d0["obs"]) or not np.array_equal(d2["obs"], d0["obs"])
        tile = first_scene(made["big"] / demo.name)["tile"]["cubes"][0]["size"]
        assert tile == pytest.approx({"x": 0.2, "y": 0.2, "z": 0.012}, abs=1e-6)
        assert first_scene(made["copy"] / demo.name) == first_scene(demo)
    # the spec changed after the logs were recorded: refused, one line per log
    big.write_text(big.read_text().replace("mass = 0.5 ", "mass = 0.6 "))
    out = tmp_path / "changed"
    r = run_cli("convert", str(outs["big"]), "--task", "suction", "--out", str(out),
                "--no-progress")  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr
    errors = r.stderr.strip().splitlines()
    assert len(errors) == 2, r.stderr
    assert all(f"task file {big} is not the spec the log was recorded with" in e for e in errors)
    assert not list(out.glob("*.mcap"))
    # --task-file points elsewhere: a missing file is named
    r = run_cli("convert", str(outs["copy"]), "--task", "suction", "--out", str(out),
                "--task-file", str(tmp_path / "gone.toml"), "--no-progress")  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"task file {tmp_path / 'gone.toml'}" in r.stderr
    # another task's spec for suction logs
    grip = spec_copy(tmp_path, "BlockGrip")
    r = run_cli("convert", str(outs["copy"]), "--task", "suction", "--out", str(out),
                "--task-file", str(grip), "--no-progress")  # fmt: skip
    assert r.returncode == 2
    assert f"task file {grip} runs the grip task, converting as suction" in r.stderr


BAD_SPECS = [
    # (edit of tile_suction.toml, what the one line must say)
    (("mass = 0.5 ", "mass = -2 "), ["object.mass = -2.0", "must be a finite number > 0"]),
    (("version = 1", "version = 2"), ["version = 2", "reads version 1"]),
    (("object_x = [0.0, 0.15]", "object_x = [0.9, 1.0]"),
     ["starts.paper.object_x = [0.9, 1.0]", "within"]),
    (("mass = 0.5 ", "masss = 0.5 "), ["line 41, column 1 (masss = 0.5)", "unknown field `masss`"]),
    (("mass = 0.5 ", 'mass = "heavy" '),
     ['line 41, column 8 (mass = "heavy")', 'invalid type: string "heavy"']),
    (('kind = "suction"', 'kind = "vacuum"'), ['(kind = "vacuum")', "unknown variant `vacuum`"]),
    (('model = "ur3"', 'model = "ur3"\njoint_step = 0'),
     ["robot.joint_step = 0.0", "must be a finite joint motion > 0"]),
    (('model = "ur3"', 'model = "ur3"\njoint_step = 0.2'),
     ["robot.joint_step = 0.2", "must be at most 0.1257 rad per step",
      "ur3's slowest rated joint speed"]),
]  # fmt: skip


def one_error_line(r, *parts: str) -> str:
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    line = lines[0]
    assert line.startswith("mimicrete synth-hands: error: --task-file ")
    for p in parts:
        assert p in line, (p, line)
    return line


BAD_PLACE_SPECS = [
    # (edit of tile_place.toml, what the one line must say)
    (("gap = 0.003", "gap = 0.06"), ["effector.seal.gap = 0.06", "below 0.05 m"]),
    (("vacuum_kpa = 60.0", "vacuum_kpa = 120.0"),
     ["effector.seal.vacuum_kpa = 120.0", "below the atmosphere's pressure"]),
    (("safety_factor = 1.5", "safety_factor = 0.5"),
     ["effector.seal.safety_factor = 0.5", "must be a finite number >= 1"]),
    (("stroke = 0.010", "stroke = -0.01"),
     ["effector.seal.stroke = -0.01", "a travel in [0, 0.05] m"]),
    (("[0.40, 0.55, 0.30]]", "[0.40, 0.55, -0.10]]"),
     ["robot.tcp_box = [[-0.4, 0.1, -0.05], [0.4, 0.55, -0.1]]", "each min below its max"]),
    (("[0.40, 0.55, 0.30]]", "[0.40, 0.55, 0.10]]"),
     ["robot.tcp_box = ", "TCP at home_q", "lies outside it"]),
    (("success_yaw_deg = 2.0", "success_yaw_deg = 50.0"),
     ["thresholds.success_yaw_deg = 50.0", "an angle in (0, 45) degrees"]),
    (("rest_steps = 3", "rest_steps = 0"), ["thresholds.rest_steps = 0", "1 to 100 steps"]),
    (('rule = "placed"   ', 'rule = "paper"   '),
     ["effector.seal = ", 'the seal runs with thresholds.rule = \"placed\"']),
    (('rule = "placed"   ', 'rule = "placd"   '), ['(rule = "placd")', "unknown variant `placd`"]),
]  # fmt: skip


#: (the built-in spec edited, the edit, what the one line must say)
BAD_TASK_FILES = [("TileSuction", *b) for b in BAD_SPECS]
BAD_TASK_FILES += [("TilePlace", *b) for b in BAD_PLACE_SPECS]


@pytest.mark.parametrize("task,edit,says", BAD_TASK_FILES, ids=[b[2][0] for b in BAD_TASK_FILES])
def test_a_bad_task_file_is_one_line_and_exit_2(tmp_path: Path, task, edit, says) -> None:
    bad = spec_copy(tmp_path, task, edit)
    out = tmp_path / "out"
    r = run_cli("synth-hands", "--task-file", str(bad), "--episodes", "1", "--out", str(out))
    one_error_line(r, f"{bad}: ", *says)
    assert not out.exists()


def test_a_task_file_that_is_no_file_or_another_task_is_refused(tmp_path: Path) -> None:
    out = str(tmp_path / "out")
    missing = tmp_path / "missing.toml"
    r = run_cli("synth-hands", "--task-file", str(missing), "--out", out)
    one_error_line(r, f"{missing}: No such file or directory")
    r = run_cli("synth-hands", "--task-file", str(tmp_path), "--out", out)
    one_error_line(r, f"{tmp_path}: Is a directory")
    garbage = tmp_path / "garbage.toml"
    garbage.write_text("not a spec [[[\n")
    one_error_line(run_cli("synth-hands", "--task-file", str(garbage), "--out", out),
                   f"{garbage}: line 1, column", "(not a spec [[[)")  # fmt: skip
    spec = spec_copy(tmp_path, "TileSuction")
    r = run_cli("synth-hands", "--task-file", str(spec), "--task", "screw", "--out", out)
    one_error_line(r, str(spec), "runs the suction task (TileSuction), not --task screw")
    assert not Path(out).exists()


def test_synth_hands_through_teleop_records_in_the_task_file(tmp_path: Path) -> None:
    """The scripted person through a live ``mimicrete teleop`` server run in the spec file: the
    demo installs the bigger tile, names the spec and draws its tile."""
    from mimicrete import demos

    big = spec_copy(tmp_path, "TileSuction", (TILE, BIG_TILE), BIG_WIDE,
                    ('success = "installed"', 'success = "laid"'))  # fmt: skip
    out = tmp_path / "live"
    r = run_cli("synth-hands", "--through-teleop", "--task-file", str(big), "--episodes", "1",
                "--seed", "2", "--out", str(out))  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "recorded 1 demos through mimicrete teleop" in r.stdout and "1 succeeded" in r.stdout
    d = demos.read(out / "suction_0000.mcap")
    assert d["meta"]["task_file"] == str(big) and d["meta"]["success"] == "true"
    tile = first_scene(out / "suction_0000.mcap")["tile"]["cubes"][0]["size"]
    assert tile == pytest.approx({"x": 0.2, "y": 0.2, "z": 0.012}, abs=1e-6)


# ----------------------------------------------------------------------------------------------
# a researcher's task end to end: synth-hands -> convert -> train -> eval, no Rust touched
# ----------------------------------------------------------------------------------------------

SMALL_TRAIN = [
    "--config", "configs/fewdemo.yaml", "--max-steps", "1024", "--num-envs", "8",
    "--no-progress", "--eval-episodes", "2",
    "--set", "behavior.hyperparameters.buffer_size=512",
    "--set", "behavior.hyperparameters.batch_size=256",
    "--set", "behavior.network_settings.hidden_units=32",
    "--set", "behavior.demo_episodes=2",
]  # fmt: skip
REPO = Path(__file__).resolve().parents[1]


def test_a_task_file_trains_and_evaluates_end_to_end(tmp_path: Path) -> None:
    """``train --task-file`` trains in the spec (its policy file, evaluation and eval.json name
    it) on demos recorded there; demos of the built-in task for a spec run, or the spec's demos
    for a built-in run, are refused naming the demo and both specs, exit 2."""
    sentence = "Install the large-format tile on the pad."
    big = spec_copy(tmp_path, "TileSuction", (TILE, BIG_TILE), BIG_WIDE, (
        'instruction = "Pick up the tile with the suction head and install it on the target pad."',
        f'instruction = "{sentence}"'))  # fmt: skip
    hands, demos_dir = tmp_path / "hands", tmp_path / "demos"
    assert run_cli("synth-hands", "--task-file", str(big), "--episodes", "2", "--seed", "5",
                   "--out", str(hands)).returncode == 0  # fmt: skip
    r = run_cli("convert", str(hands), "--task", "suction", "--out", str(demos_dir),
                "--no-progress")  # fmt: skip
    assert r.returncode == 0, r.stderr
    run = tmp_path / "run"
    r = run_cli("train", *SMALL_TRAIN, "--task-file", str(big), "--demos", str(demos_dir),
                "--run-dir", str(run), cwd=REPO)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    resolved = (run / "resolved_config.yaml").read_text()
    assert "env_id: Task-v0" in resolved and f"task_file: {big}" in resolved
    r = run_cli("eval", str(run), "--episodes", "2", "--starts", "wide", cwd=REPO)
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.loads((run / "eval_wide.json").read_text())
    assert res["env_id"] == "Task-v0" and res["task_file"] == str(big) and res["episodes"] == 2
    # exported for LeRobot: replayed in the spec, its sentence the dataset's task text
    r = run_cli("export", str(demos_dir), "--format", "lerobot", "--out", str(tmp_path / "lr"))
    assert r.returncode == 0, r.stderr[-2000:]
    import pyarrow.parquet as pq

    assert pq.read_table(tmp_path / "lr/meta/tasks.parquet").to_pylist() == [
        {"task_index": 0, "task": sentence}
    ]
    # demogen generates in the spec: its demos start at the spec's wide starts, name the spec,
    # and train in it
    gen = tmp_path / "gen"
    r = run_cli("demogen", "--demos", str(demos_dir), "--source-count", "2", "--count", "4",
                "--starts", "wide", "--out", str(gen), "--seed", "0", "--no-progress")  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    from mimicrete import demos as demo_files

    d = demo_files.load(gen)
    assert d.num_episodes == 4 and all(m["task_file"] == str(big) for m in d.metas)
    assert all(m["success"] == "true" for m in d.metas)
    # at the spec's own wide starts (its box begins at x = 0.07 m, the built-in one at 0.035)
    xs = [json.loads(m["object_pose"])[0] for m in d.metas]
    assert all(0.07 - 1e-6 <= x <= 0.285 + 1e-6 for x in xs), xs
    first = demo_files.read(sorted(gen.glob("*.mcap"))[0])
    assert json.loads(first["meta"]["task_spec"])["object"]["half_extents"] == [0.1, 0.1, 0.006]
    r = run_cli("train", *SMALL_TRAIN, "--task-file", str(big), "--demos", str(gen),
                "--run-dir", str(tmp_path / "run_gen"), cwd=REPO)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    # the built-in task's demos for the spec run, and the spec's demos for a built-in run
    builtin = tmp_path / "builtin_demos"
    run_cli("synth-hands", "--episodes", "2", "--seed", "5", "--out", str(tmp_path / "h0"))
    run_cli("convert", str(tmp_path / "h0"), "--task", "suction", "--out", str(builtin),
            "--no-progress")  # fmt: skip
    for extra, demos_path, says in [
        (["--task-file", str(big)], builtin,
         f"a demo recorded in TileSuction's built-in spec, the run trains in {big}"),
        ([], demos_dir,
         f"a demo recorded in {big}, the run trains in TileSuction's built-in spec "
         "(train it with --task-file)"),
    ]:  # fmt: skip
        r = run_cli("train", *SMALL_TRAIN, *extra, "--demos", str(demos_path),
                    "--run-dir", str(tmp_path / "refused"), cwd=REPO)  # fmt: skip
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr[-2000:]
        assert says in r.stderr, r.stderr
    # the spec changed since: the export cannot replay there and says so
    big.write_text(big.read_text().replace("mass = 0.5 ", "mass = 0.7 "))
    r = run_cli("export", str(demos_dir), "--format", "lerobot", "--out", str(tmp_path / "lr2"))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"task file {big} is not the spec the demo was recorded in" in r.stderr
    # a config for another task than the spec runs: refused before anything trains
    r = run_cli("train", "--config", "configs/wide_gen_screw.yaml", "--task-file",
                str(big), "--demos", str(demos_dir), "--run-dir", str(tmp_path / "other"),
                cwd=REPO)  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"--task-file {big} runs TileSuction, but the config trains Screw-v0" in r.stderr
    assert not (tmp_path / "other").exists()
    # a bad spec is one line before anything trains
    bad = spec_copy(tmp_path, "TileSuction", ("mass = 0.5 ", "mass = -2 "))
    r = run_cli("train", *SMALL_TRAIN, "--task-file", str(bad), "--demos", str(demos_dir),
                "--run-dir", str(tmp_path / "bad"), cwd=REPO)  # fmt: skip
    assert r.returncode == 2 and "object.mass = -2.0" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "bad").exists()
