"""Object-centric demo generation (``mimicrete demogen``): the segment transform, generation
through the real simulator from one recorded demo, and the CLI's bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tests._cli_run import run_cli

from mimicrete import _native, demos, kin
from mimicrete import demogen as dg
from mimicrete.demogen import generator as gen
from mimicrete.demogen.generator import GeneratedEpisode, _Runner


@pytest.fixture(scope="module")
def source_dir(tmp_path_factory):
    """One real MCAP demo at a paper start: tile-sim's scripted expert driving the simulator,
    every step recorded through the project's demo writer."""
    out = tmp_path_factory.mktemp("src")
    sim = _native.SimEnv("TileSuction", 0)
    expert = _native.SimExpert("TileSuction")
    obs = sim.reset(11)
    expert.reset()
    ep = GeneratedEpisode("expert", {"object_pose": list(sim.start()["object_pose"])}, 11)
    run = _Runner(sim, ep, np.asarray(obs, np.float32))
    for _ in range(700):
        a = np.asarray(expert.act(sim), np.float64)
        target = kin.fk(run.q + a[:6] * gen.MAX_JOINT_STEP, model="ur3")
        try:
            run.step(target, float(a[6]))
        except gen._Abort:
            break
    assert ep.installed, "the scripted expert should install from a paper start"
    dg.write_episode(ep, out / "src_0000.mcap", 0)
    return out


def test_a_transformed_segment_lands_in_the_new_object_frame(source_dir):
    (src,) = dg.load_sources(source_dir)
    approach, place = src.segments
    assert approach.relative_to == "object" and place.relative_to == "target"
    dst = dg.frame(0.21, 0.35, 0.005, np.radians(25.0))
    moved = approach.moved_to(dst)
    # every pose keeps its pose relative to the frame: src⁻¹·P == dst⁻¹·P'
    rel_src = np.linalg.inv(approach.src) @ approach.poses
    rel_dst = np.linalg.inv(dst) @ moved
    np.testing.assert_allclose(rel_dst, rel_src, atol=1e-9)
    # the grasp pose (the segment's end) sits above the new tile as it sat above the old one
    tcp_above = approach.poses[-1][:3, 3] - approach.src[:3, 3]
    c, s = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    want = dst[:3, 3] + np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ tcp_above
    np.testing.assert_allclose(moved[-1][:3, 3], want, atol=1e-6)
    # the tool stays a rigid transform (pointing down, turned by the yaw)
    np.testing.assert_allclose(
        moved[:, :3, :3] @ moved[:, :3, :3].transpose(0, 2, 1),
        np.broadcast_to(np.eye(3), moved[:, :3, :3].shape),
        atol=1e-9,
    )


def test_generation_from_one_demo_installs_at_new_starts(source_dir, tmp_path):
    sources = dg.load_sources(source_dir, 1)
    starts = dg.draw_starts(6, seed=3, starts="wide")
    rep = dg.generate(sources, 6, tmp_path, starts=starts, seed=3, max_attempts=6)
    assert rep.attempts == 6 and rep.kept >= 5, rep.failures
    d = demos.load(tmp_path)
    assert d.num_episodes == rep.kept
    for meta, path in zip(d.metas, d.files, strict=True):
        assert meta["generated"] == "true" and meta["source_demo"] == "src_0000.mcap"
        assert meta["success"] == "true"
        pose = json.loads(meta["object_pose"])
        # the demo really starts there: its first observation holds the new tile
        first = demos.load(path).obs[0, -16:]
        np.testing.assert_allclose(first[13:15], pose[:2], atol=1e-5)
    # the new starts lie outside the source's (paper) start
    src_x = sources[0].tile[0]
    assert max(abs(json.loads(m["object_pose"])[0] - src_x) for m in d.metas) > 0.03
    # the installs are real: the last step of each generated demo is rewarded and terminal
    for sl in d.episode_slices():
        assert d.terminated[sl][-1] and d.rewards[sl].sum() >= 2.0 - 1e-6


def test_cli_bad_input_exits_2_naming_the_problem(source_dir, tmp_path):
    r = run_cli(
        "demogen", "--demos", str(tmp_path / "nope"), "--count", "3", "--out", str(tmp_path / "o")
    )
    assert r.returncode == 2 and "--demos" in r.stderr and "no such file" in r.stderr, r.stderr
    r = run_cli("demogen", "--demos", str(source_dir), "--count", "0", "--out", str(tmp_path))
    assert r.returncode == 2 and "--count" in r.stderr, r.stderr
    r = run_cli(
        "demogen",
        "--demos",
        str(source_dir),
        "--count",
        "2",
        "--starts",
        "everywhere",
        "--out",
        str(tmp_path / "o2"),
    )
    assert r.returncode == 2 and "--starts everywhere" in r.stderr, r.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    r = run_cli("demogen", "--demos", str(empty), "--count", "2", "--out", str(tmp_path / "o3"))
    assert r.returncode == 2 and "no *.mcap" in r.stderr, r.stderr


def test_cli_writes_demos_with_a_summary(source_dir, tmp_path):
    out = tmp_path / "gen"
    r = run_cli(
        "demogen",
        "--demos",
        str(source_dir),
        "--count",
        "2",
        "--starts",
        "wide",
        "--out",
        str(out),
        "--seed",
        "1",
        "--no-progress",
    )
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "demogen.json").read_text())
    assert summary["kept"] == 2 and summary["attempts"] >= 2
    assert "yield" in r.stdout
