"""TileRow (issue 26 §2) from Python: the task table's ``row``, its gymnasium ids and spec file,
an episode of the Rust expert through the gym env, the scripted person's row through the real
teleop path (synth-hands, convert, and live through a teleop server), its demos' scene and
export, and demogen, not built for a row yet, refusing it in one line, exit 2, through the real
command line."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from mimicrete import _native, envs, tasks
from mimicrete.gestures.classes import TASK_MODEL

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _cli_run import run_cli  # noqa: E402

ROW_SPEC = Path(__file__).resolve().parents[1] / "crates" / "tile-sim" / "tasks" / "tile_row.toml"
# q[6], suction, cup centre[3], the current tile's target[3] and centre[3], its centre minus the
# cup's[3] and its target minus its centre[3], then per tile: its target[3], centre[3], installed
# flag
FRAME = 43
TILES = 3


def tile(frame: np.ndarray, i: int) -> dict[str, np.ndarray]:
    """Tile ``i``'s fields of one observation frame."""
    base = 22 + 7 * i
    return {
        "target": frame[base : base + 3],
        "centre": frame[base + 3 : base + 6],
        "installed": frame[base + 6],
    }


def test_the_row_is_a_task_of_the_table() -> None:
    row = tasks.get("row")
    for name in ("TileRow", "tile_row", "TileRow-v0", "mimicrete/TileRow-v0", "ROW"):
        assert tasks.get(name) is row
    assert (row.sim, row.env_id) == ("TileRow", "mimicrete/TileRow-v0")
    assert "row" in tasks.TASKS and "TileRow" in tasks.SIM_TASKS and row.env_id in tasks.ENV_IDS
    # every fact of the row comes from its spec and the simulator
    spec = _native.task_spec("TileRow")
    assert row.builtin_spec() == spec and spec["row"]["count"] == TILES
    assert row.effector == spec["effector"]["kind"] == "suction"
    assert row.gesture_model == spec["about"]["gestures"] == "grip" == TASK_MODEL["row"]
    assert row.success == spec["about"]["success"]
    assert row.instruction == spec["about"]["instruction"]
    assert row.max_steps == spec["episode"]["max_steps"] == 2000
    dims = _native.sim_constants()["tasks"]["TileRow"]
    assert (row.obs_frame_dim, row.obs_dim, row.act_dim) == (
        dims["obs_frame_dim"],
        dims["obs_dim"],
        dims["act_dim"],
    )
    assert (row.obs_frame_dim, row.obs_dim, row.act_dim) == (FRAME, 5 * FRAME, 7)


def test_the_gym_id_resets_and_steps_with_the_row_frame() -> None:
    env = gym.make("mimicrete/TileRow-v0")
    assert isinstance(env.unwrapped, envs.TileRowEnv) and env.unwrapped.task == "TileRow"
    assert env.spec is not None and env.spec.max_episode_steps is None  # the sim truncates
    assert env.observation_space.shape == (5 * FRAME,) and env.action_space.shape == (7,)
    obs, info = env.reset(seed=4)
    assert obs.shape == (5 * FRAME,) and obs.dtype == np.float32
    assert np.all(obs[: 4 * FRAME] == 0.0)  # zero-padded at the start
    frame = obs[4 * FRAME :]
    snap = env.unwrapped.sim.snapshot()
    np.testing.assert_allclose(frame[:6], _native.sim_constants()["HOME_Q"], atol=1e-6)
    assert frame[6] == -1.0  # suction off
    np.testing.assert_allclose(frame[7:10], snap["tcp"]["t"], atol=1e-5)
    # the current tile (tile 0 at the start) where TileSuction's frame has its tile
    np.testing.assert_allclose(frame[10:13], snap["row"][0]["target"]["t"], atol=1e-5)
    np.testing.assert_allclose(frame[13:16], snap["row"][0]["object"]["t"], atol=1e-5)
    np.testing.assert_allclose(frame[16:19], frame[13:16] - frame[7:10], atol=1e-6)  # tile - cup
    np.testing.assert_allclose(frame[19:22], frame[10:13] - frame[13:16], atol=1e-6)
    assert len(snap["row"]) == TILES
    for i, rec in enumerate(snap["row"]):
        t = tile(frame, i)
        np.testing.assert_allclose(t["target"], rec["target"]["t"], atol=1e-5)
        np.testing.assert_allclose(t["centre"], rec["object"]["t"], atol=1e-5)
        assert t["installed"] == 0.0 and not rec["installed"] and not rec["picked"]
    # the paper's row starts: tile 0 at x in [-0.20, -0.14], its neighbours 0.17 m on
    xs = [tile(frame, i)["centre"][0] for i in range(TILES)]
    assert -0.2 - 1e-6 <= xs[0] <= -0.14 + 1e-6
    np.testing.assert_allclose(np.diff(xs), 0.17, atol=1e-5)
    obs2, r, term, trunc, info = env.step(np.zeros(7, np.float32))
    assert obs2.shape == (5 * FRAME,) and np.array_equal(obs2[3 * FRAME : 4 * FRAME], frame)
    assert r == 0.0 and not term and not trunc
    assert set(info) >= {"picked", "installed", "fell", "held"}
    img = gym.make("mimicrete/TileRow-v0", render_mode="rgb_array")
    img.reset(seed=4)
    rgb = img.render()
    assert rgb.dtype == np.uint8 and rgb.ndim == 3


def test_the_vector_entry_gives_the_row() -> None:
    vec = gym.make_vec("mimicrete/TileRow-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(vec, envs.MimicreteVecEnv) and vec.task == "TileRow"
    assert vec.observation_space.shape == (2, 5 * FRAME) and vec.action_space.shape == (2, 7)
    obs, _ = vec.reset(seed=9)
    single = _native.SimEnv("TileRow", 0)
    np.testing.assert_array_equal(single.reset(10), obs[1])  # env i: episode seed + i
    obs, rew, term, trunc, _ = vec.step(np.zeros((2, 7), np.float32))
    assert obs.shape == (2, 5 * FRAME) and not term.any() and not trunc.any()


def run_expert(env: gym.Env, seed: int) -> tuple[list[float], np.ndarray, bool, bool, int]:
    """One episode of the Rust expert through ``env`` → rewards, last obs, terminated,
    truncated, steps."""
    sim = env.unwrapped.sim
    expert = _native.SimExpert("TileRow")
    env.reset(seed=seed)
    expert.reset()
    rewards: list[float] = []
    term = trunc = False
    obs = None
    while not (term or trunc):
        obs, r, term, trunc, info = env.step(expert.act(sim))
        rewards.append(r)
    assert info["installed"] == term  # the last install ends it (no fall)
    return rewards, obs, term, trunc, len(rewards)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_rust_expert_installs_the_row_through_the_gym_env(seed: int) -> None:
    rewards, obs, term, trunc, steps = run_expert(gym.make("mimicrete/TileRow-v0"), seed)
    assert term and not trunc and steps < tasks.get("row").max_steps
    assert sum(rewards) == 6.0  # each tile's pick +1 and its install +1
    assert sorted(r for r in rewards if r != 0.0) == [1.0] * 6
    last = obs[-FRAME:]
    assert [tile(last, i)["installed"] for i in range(TILES)] == [1.0] * TILES
    for i in range(TILES):  # each tile within the install distance of its pad's target
        t = tile(last, i)
        assert np.linalg.norm(t["centre"] - t["target"]) < 0.03


def test_the_row_spec_file_runs_as_the_builtin_row() -> None:
    task, spec = tasks.load_task_file(ROW_SPEC)
    assert task is tasks.get("row") and spec == _native.task_spec("TileRow")
    mine = gym.make("mimicrete/Task-v0", spec=str(ROW_SPEC))
    assert mine.unwrapped.task == "TileRow" and mine.observation_space.shape == (5 * FRAME,)
    builtin = gym.make("mimicrete/TileRow-v0")
    a, b = run_expert(mine, 5), run_expert(builtin, 5)
    assert a[0] == b[0] and np.array_equal(a[1], b[1]) and a[2:] == b[2:]
    vec = envs.make_vec("Task-v0", 2, seed=0, spec=ROW_SPEC)
    assert vec.task == "TileRow" and vec.observation_space.shape == (2, 5 * FRAME)


# ----------------------------------------------------------------------------------------------
# What is not built for a row yet: one line, exit 2, through the real command line
# ----------------------------------------------------------------------------------------------


def one_line(r, command: str, *parts: str) -> str:
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith(f"mimicrete {command}: error: "), lines[0]
    assert "Traceback" not in r.stderr
    for p in parts:
        assert p in lines[0], (p, lines[0])
    return lines[0]


# ----------------------------------------------------------------------------------------------
# The scripted person demonstrates the row; its hand logs convert to demos that install it
# ----------------------------------------------------------------------------------------------


def test_the_demonstrator_plans_three_picks_and_places_in_row_order() -> None:
    from mimicrete.demonstrator import TASKS, Person, plan_task, scene_from_env

    assert "row" in TASKS and set(TASKS) == set(tasks.TASKS)
    sc = scene_from_env("row", 7)
    env = _native.SimEnv("TileRow")
    env.reset(7)
    snap = env.snapshot()
    assert sc.objects is not None and sc.targets is not None and len(sc.objects) == TILES
    for i, r in enumerate(snap["row"]):
        np.testing.assert_allclose(sc.objects[i], r["object"]["t"], atol=1e-6)
        np.testing.assert_allclose(sc.targets[i], r["target"]["t"], atol=1e-6)
    assert [list(map(list, p)) for p in sc.picks()] == [
        [list(o), list(t)] for o, t in zip(sc.objects, sc.targets, strict=True)
    ]
    rng = np.random.default_rng(0)
    m = plan_task(sc, rng, Person.draw(rng, "right"))
    pos, _, phases, _ = m.arrays()
    labels, _ = m.gestures()
    # three closes, each over its tile's grasp point; three releases, each over its pad's target
    closes = [k for k in range(1, len(phases)) if phases[k] == "close" and phases[k - 1] != "close"]
    releases = [
        k for k in range(1, len(phases)) if phases[k] == "release" and phases[k - 1] != "release"
    ]
    assert len(closes) == len(releases) == TILES
    for i in range(TILES):
        assert closes[i] < releases[i] and (i == 0 or releases[i - 1] < closes[i])
        np.testing.assert_allclose(pos[closes[i]][:2], sc.objects[i][:2], atol=0.02)
        np.testing.assert_allclose(pos[releases[i]][:2], sc.targets[i][:2], atol=0.02)
    assert labels.count("closing") > 0 and labels[-1] == "opening"


def synth_and_convert(out: Path, *how: str) -> Path:
    """Two scripted rows through the real command line (synth-hands, then convert) into
    ``out/demos``; asserts both install."""
    hands, demos = out / "hands", out / "demos"
    r = run_cli("synth-hands", *how, "--episodes", "2", "--seed", "3", "--out", str(hands))
    assert r.returncode == 0, r.stderr
    logs = sorted(hands.glob("*.handlog.jsonl"))
    assert [p.name for p in logs] == ["row_0000.handlog.jsonl", "row_0001.handlog.jsonl"]
    r = run_cli("convert", str(hands), "--task", "row", "--out", str(demos), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert "2 demos in" in r.stdout and "2 installed (100.0 %), 0 logs failed" in r.stdout
    return demos


@pytest.fixture(scope="module")
def row_demos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return synth_and_convert(tmp_path_factory.mktemp("row"), "--task", "row")


def messages(mcap: Path, topic: str) -> list[dict]:
    from mcap.reader import make_reader

    with open(mcap, "rb") as f:
        return [json.loads(m.data) for _, _, m in make_reader(f).iter_messages([topic])]


def test_synth_hands_then_convert_installs_the_row(row_demos: Path) -> None:
    for mcap in sorted(row_demos.glob("*.mcap")):
        steps = messages(mcap, "/demo/step")
        rewards = [s["reward"] for s in steps]
        # three picks and three installs pay +1 each; the last step installs the third tile
        assert sum(rewards) == pytest.approx(6.0) and steps[-1]["terminated"]
        assert len(steps) <= tasks.get("row").max_steps


def test_the_row_from_its_spec_file_installs_too(tmp_path: Path) -> None:
    synth_and_convert(tmp_path, "--task-file", str(ROW_SPEC))


def test_a_row_demo_draws_and_moves_every_tile(row_demos: Path) -> None:
    mcap = sorted(row_demos.glob("*.mcap"))[0]
    (scene,) = messages(mcap, "/scene")[:1]
    ents = {e["id"]: e for e in scene["entities"]}
    for i in range(TILES):
        assert ents[f"tile_{i}"]["frame_id"] == f"tile_{i}"
        assert ents[f"pad_{i}"]["frame_id"] == "base"
    steps, tfs = messages(mcap, "/demo/step"), messages(mcap, "/tf")
    assert len(tfs) == len(steps)
    for k in (0, len(steps) // 2, len(steps) - 1):
        frames = {t["child_frame_id"]: t["translation"] for t in tfs[k]["transforms"]}
        # each tile's frame is where the observation of the step after has that tile
        after = np.array(steps[k + 1]["obs"][-FRAME:]) if k + 1 < len(steps) else None
        for i in range(TILES):
            xyz = [frames[f"tile_{i}"][a] for a in "xyz"]
            if after is not None:
                np.testing.assert_allclose(xyz, tile(after, i)["centre"], atol=1e-5)
    # at the end every tile lies on its pad's target
    last = {t["child_frame_id"]: t["translation"] for t in tfs[-1]["transforms"]}
    final = np.array(steps[-1]["obs"][-FRAME:])
    for i in range(TILES):
        xyz = np.array([last[f"tile_{i}"][a] for a in "xyz"])
        assert np.linalg.norm(xyz - tile(final, i)["target"]) < 0.03


def test_a_row_exports_to_lerobot_with_each_tiles_fields(row_demos: Path, tmp_path: Path) -> None:
    import pyarrow.parquet as pq

    from mimicrete import demos

    out = tmp_path / "lr"
    r = run_cli("export", str(row_demos), "--format", "lerobot", "--out", str(out))
    assert r.returncode == 0, r.stderr
    info = json.loads((out / "meta/info.json").read_text())
    names = info["features"]["observation.state"]["names"]
    assert names[-FRAME:][16:22] == [
        f"t.{w}_{a}" for w in ("tile_from_cup", "target_from_tile") for a in "xyz"
    ]
    assert len(names) == 5 * FRAME and names[-FRAME:][22:29] == [
        "t.target0_x", "t.target0_y", "t.target0_z", "t.tile0_x", "t.tile0_y", "t.tile0_z",
        "t.installed0",
    ]  # fmt: skip
    assert names[-1] == "t.installed2"
    assert info["features"]["action"]["names"][-1] == "suction_level"
    d = demos.load(row_demos)
    state = np.stack(pq.read_table(out / "data/chunk-000/file-000.parquet")
                     .column("observation.state").to_pylist())  # fmt: skip
    np.testing.assert_array_equal(state.astype(np.float32), d.obs)
    eps = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert eps[0]["tasks"] == [tasks.get("row").instruction]


def test_the_demonstrator_refuses_an_unknown_task(tmp_path: Path) -> None:
    from mimicrete.demonstrator import synth_hands

    with pytest.raises(ValueError, match="unknown task"):
        synth_hands("bricks", 1, 0, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_demogen_refuses_the_row(tmp_path: Path) -> None:
    from mimicrete import demogen as dg

    with pytest.raises(tasks.NotBuiltError, match="demogen is not built for the row task"):
        dg.task_frames("TileRow")
    out = tmp_path / "out"
    r = run_cli("demogen", "--demos", str(tmp_path), "--task", "row", "--count", "1",
                "--out", str(out))  # fmt: skip
    one_line(r, "demogen", "demogen is not built for the row task (TileRow) yet; "
             "it handles suction, grip, screw")  # fmt: skip
    assert not out.exists()


@pytest.mark.slow
def test_a_row_is_recorded_live_through_a_teleop_server(tmp_path: Path) -> None:
    """``synth-hands --through-teleop``: IWER's Quest-captured hand shapes over the page's
    protocol into a real ``mimicrete teleop --task row`` server; the demo installs the row and
    its scene draws every tile in its own frame."""
    out = tmp_path / "live"
    r = run_cli("synth-hands", "--task", "row", "--through-teleop", "--episodes", "1",
                "--seed", "0", "--out", str(out), timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "1 succeeded" in r.stdout, r.stdout
    demo = out / "row_0000.mcap"
    steps = messages(demo, "/demo/step")
    assert sum(s["reward"] for s in steps) == pytest.approx(6.0) and steps[-1]["terminated"]
    ents = {e["id"]: e for e in messages(demo, "/scene")[0]["entities"]}
    assert [ents[f"tile_{i}"]["frame_id"] for i in range(TILES)] == ["tile_0", "tile_1", "tile_2"]


def test_the_demos_needed_experiment_offers_the_row() -> None:
    from mimicrete.experiments.demos_needed import build_parser

    assert build_parser().parse_args(["--task", "row"]).task == "row"
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args(["--task", "bricks"])
    assert e.value.code == 2
