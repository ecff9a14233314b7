"""TilePlace's demonstration chain through the real command line: the scripted person's hand
logs (``synth-hands --task place``) converted through the teleoperation path (``convert``) place
the tile, and ``demogen`` carries five of those demos to the wide starts (the tile turned, the
pad moved and turned), keeping only placements that replay as placed."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from mimicrete import _native
from mimicrete import demonstrator as sy

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _cli_run import run_cli  # noqa: E402

EPISODES = 10


def placement_of(seed: int, actions: np.ndarray, start: dict | None = None) -> tuple[bool, dict]:
    """Replay ``actions`` in a fresh TilePlace env reset at ``seed`` (at ``start`` if given):
    whether the episode ended placed, and where the tile was when it ended."""
    env = _native.SimEnv("TilePlace", 0)
    env.reset(int(seed), **(start or {}))
    for a in np.asarray(actions, np.float32):
        _, _, term, trunc, info = env.step(a)
        if term or trunc:
            return bool(info["installed"]), env.last_placement()
    return False, env.placement()


@pytest.fixture(scope="module")
def place_demos(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Ten scripted placements through the real command line: hand logs, then MCAP demos."""
    root = tmp_path_factory.mktemp("place")
    hands, demos = root / "hands", root / "demos"
    r = run_cli(
        "synth-hands", "--task", "place", "--episodes", str(EPISODES), "--seed", "0",
        "--out", str(hands),
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    r = run_cli("convert", str(hands), "--task", "place", "--out", str(demos), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert f"{EPISODES} demos in" in r.stdout and "0 logs failed" in r.stdout, r.stdout
    return demos


def test_the_scripted_person_places_the_tile_through_the_teleop_path(place_demos: Path) -> None:
    placed = 0
    for path in sorted(place_demos.glob("*.mcap")):
        d = _native.demo_read(str(path))
        meta, actions = d["meta"], np.asarray(d["actions"])
        # the demo says what the simulator says when its actions are replayed
        ok, where = placement_of(int(meta["seed"]), actions)
        assert ok == (meta["success"] == "true"), (path.name, where)
        placed += ok
        if ok:  # placed as a tiler means it: let go, square and centred on the pad
            assert not where["held"] and where["xy_error"] <= 0.005, where
            assert abs(where["yaw_error_deg"]) <= 2.0, where
            assert all(abs(g) <= 0.003 for g in where["hold_gaps"]), where
        # the suction is commanded only where it switches: on once at the tile, off once
        switched = actions[np.flatnonzero(actions[:, 6]), 6].tolist()
        assert switched == [1.0, -1.0], (path.name, switched)
    assert placed >= 9, f"{placed} of {EPISODES} placed"


def test_the_person_looks_before_setting_the_tile_down(place_demos: Path) -> None:
    """Each hand log records the one look, at the set-down: what the person saw (the tile off
    its target by a few millimetres, turned from square by under a couple of degrees)."""
    logs = sorted((place_demos.parent / "hands").glob("*.handlog.jsonl"))
    assert len(logs) == EPISODES
    for log in logs:
        look = json.loads(log.read_text().splitlines()[0])["extra"]["look"]
        assert np.hypot(*look["target_minus_object_mm"]) < 15.0, look
        assert abs(look["turn_to_square_deg"]) < 5.0, look


def test_the_person_turns_the_head_square_to_the_tile_and_the_tile_square_to_the_pad() -> None:
    """At a turned tile and pad the plan turns the tool over the tile to lie square to it (the
    least turn, modulo 90°), and over the carry by the tile's turn from square to the pad."""

    def plan(scene: sy.Scene) -> tuple[np.ndarray, np.ndarray]:
        person = sy.Person.draw(np.random.default_rng(1), "right")
        motion = sy.plan_task(scene, np.random.default_rng(0), person)
        return np.degrees(motion.yaws()), np.asarray(motion.phase)

    scene = sy.scene_from_env("place", 4)
    scene.object_yaw, scene.target_yaw = np.radians(70.0), np.radians(-12.0)
    yaw, phases = plan(scene)
    assert yaw[0] == 0.0  # straight down at the start
    # 70° is square to -20° (modulo 90°): the least turn from straight down
    np.testing.assert_allclose(yaw[phases == "grasp"], -20.0, atol=1e-9)
    # the tile at 70° lies square to the pad at -12° after a turn of +8° (-82° + 90°)
    np.testing.assert_allclose(yaw[phases == "place"], -12.0, atol=1e-9)
    # the other tasks' persons keep the tool straight down
    assert not np.any(plan(sy.scene_from_env("suction", 4))[0])


def test_demogen_carries_five_placements_to_the_wide_starts(
    place_demos: Path, tmp_path: Path
) -> None:
    out = tmp_path / "gen"
    r = run_cli(
        "demogen", "--demos", str(place_demos), "--source-count", "5", "--count", "20",
        "--starts", "wide", "--seed", "0", "--out", str(out), "--no-progress",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "demogen.json").read_text())
    assert summary["task"] == "TilePlace" and summary["kept"] == 20
    assert summary["kept"] / summary["attempts"] >= 0.8, summary
    turned_tiles = turned_pads = 0
    for path in sorted(out.glob("gen_*.mcap")):
        d = _native.demo_read(str(path))
        meta = d["meta"]  # the start it was generated at: the pad's turn where it was turned
        keys = ("object_pose", "target_offset", "pad_yaw")
        start = {k: json.loads(meta[k]) for k in keys if k in meta}
        ok, where = placement_of(int(meta["seed"]), d["actions"], start)
        assert ok and where["xy_error"] <= 0.005 and abs(where["yaw_error_deg"]) <= 2.0, where
        turned_tiles += abs(start["object_pose"][2]) > np.radians(10.0)
        turned_pads += abs(start.get("pad_yaw", 0.0)) > np.radians(5.0)
    # the wide starts turn the tile by up to 30° and the pad by up to 15°: squaring is exercised
    assert turned_tiles >= 5 and turned_pads >= 5, (turned_tiles, turned_pads)


def test_demogen_played_three_times_faster_still_places_in_a_third_of_the_steps(
    place_demos: Path, tmp_path: Path
) -> None:
    out = tmp_path / "fast"
    r = run_cli(
        "demogen", "--demos", str(place_demos), "--source-count", "5", "--count", "10",
        "--starts", "wide", "--seed", "1", "--speed", "3", "--out", str(out), "--no-progress",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert json.loads((out / "demogen.json").read_text())["speed"] == 3.0
    sources = {p.name: len(_native.demo_read(str(p))["actions"]) for p in place_demos.glob("*")
               if p.suffix == ".mcap"}  # fmt: skip
    for path in sorted(out.glob("gen_*.mcap")):
        d = _native.demo_read(str(path))
        meta = d["meta"]
        assert meta["speed"] == "3.0"
        start = {k: json.loads(meta[k]) for k in ("object_pose", "target_offset", "pad_yaw")
                 if k in meta}  # fmt: skip
        ok, where = placement_of(int(meta["seed"]), d["actions"], start)
        assert ok and where["xy_error"] <= 0.005 and abs(where["yaw_error_deg"]) <= 2.0, where
        # a third of the source's steps, plus the waits that do not shrink (the seal, the rest)
        assert len(d["actions"]) <= 0.45 * sources[meta["source_demo"]], path.name


def test_the_curriculum_replays_a_generated_demo_at_its_turned_pad(tmp_path: Path) -> None:
    """A generated demo's start (the tile turned, the pad moved and turned) is where the reverse
    curriculum replays it: the replayed state is the recorded one."""
    from mimicrete import demogen as dg
    from mimicrete import envs
    from mimicrete.learn.curriculum import demo_tracks
    from mimicrete.learn.demo_data import read_demos

    src = tmp_path / "src"
    r = run_cli("synth-hands", "--task", "place", "--episodes", "1", "--seed", "5",
                "--out", str(tmp_path / "hands"))  # fmt: skip
    assert r.returncode == 0, r.stderr
    r = run_cli("convert", str(tmp_path / "hands"), "--task", "place", "--out", str(src))
    assert r.returncode == 0, r.stderr
    starts = [s for s in dg.draw_starts(40, 3, "wide", "TilePlace") if abs(s["pad_yaw"]) > 0.1]
    out = tmp_path / "gen"
    rep = dg.generate(dg.load_sources(src), 1, out, starts=starts[:1])
    assert rep.kept == 1, rep.failures
    (track,) = demo_tracks(read_demos(out, None))
    assert track.start is not None and track.start["pad_yaw"] == pytest.approx(starts[0]["pad_yaw"])
    recorded = np.asarray(_native.demo_read(str(rep.files[0]))["obs"])
    env = envs.make_vec("TilePlace-v0", 1, 0)
    k = track.length // 2
    obs = env.reset_replay(0, track.seed, track.actions[:k], track.start)
    np.testing.assert_allclose(obs, recorded[k], atol=1e-4)


PLACE_CONFIG = """\
behaviors:
  TilePlace:
    trainer_type: ppo
    hyperparameters: {{batch_size: 256, buffer_size: 512, learning_rate: 0.0003, num_epoch: 1}}
    network_settings: {{normalize: true, hidden_units: 32, num_layers: 2}}
    reward_signals:
      extrinsic: {{gamma: 0.99, strength: 1.0}}
    behavioral_cloning:
      demo_path: {root}/demos/gen_place
      strength: 0.5
      steps: 1024
      pretrain_steps: 5
      samples_per_update: 512
      generate_from: {root}/demos/place
      generate_sources: 5
      generate_count: 6
    demo_curriculum: {{reset_prob: 0.8, step_fraction: 0.05, window: 4, pooled: true}}
    max_steps: 1024
    time_horizon: 128
    summary_freq: 512
env_settings: {{env_id: TilePlace-v0, num_envs: 4, seed: 0}}
torch_settings: {{device: cpu, num_threads: 1}}
"""


@pytest.mark.slow
def test_train_make_demos_makes_the_configs_tasks_demos(tmp_path: Path) -> None:
    """``mimicrete train --make-demos`` with a TilePlace config that generates its demos makes
    TilePlace hand demos (not TileSuction's), generates from them and trains on the pooled
    reverse curriculum over the generated demos (their turned pads replayed)."""
    cfg = tmp_path / "place.yaml"
    cfg.write_text(PLACE_CONFIG.format(root=tmp_path))
    r = run_cli("train", "--config", str(cfg), "--make-demos", "--run-dir", str(tmp_path / "run"),
                "--no-progress", "--eval-episodes", "0", timeout=1200)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert f"demos: {tmp_path}/demos/place has 0 episodes, making 60" in r.stdout, r.stdout
    assert f"demos: {tmp_path}/demos/gen_place has 0 episodes, generating 6" in r.stdout
    for d in (tmp_path / "demos/place", tmp_path / "demos/gen_place"):
        metas = [_native.demo_read(str(p))["meta"] for p in sorted(d.glob("*.mcap"))]
        assert len(metas) == (60 if d.name == "place" else 6)
        assert {m["task"] for m in metas} == {"TilePlace"}
    assert "trained 1024 steps" in r.stdout
