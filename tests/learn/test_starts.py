"""Explicit and wide starts: reset options on the single and the vector env, and
`mimicrete eval --starts training|wide|FILE.jsonl` through the real CLI (results, the eval file's
record of the starts, and every bad-input path: file:line: reason, exit 2, no traceback)."""

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from tests._cli_run import run_cli

import mimicrete as mc

POLICY = Path(__file__).parent / "data" / "group3_policy.pt"


@pytest.fixture()
def run_dir(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "policy.pt").write_bytes(POLICY.read_bytes())
    return run


def test_reset_options_place_the_tile_and_the_target():
    env = gym.make("mimicrete/TileSuction-v0")
    obs, info = env.reset(
        seed=0, options={"object_pose": [0.2, 0.3, 0.3], "target_offset": [0.02, -0.03]}
    )
    assert np.allclose(info["start"]["object_pose"], [0.2, 0.3, 0.3], atol=1e-6)
    assert np.allclose(info["start"]["pad_offset"], [0.02, -0.03], atol=1e-6)
    # the newest frame's target and tile entries (frame: q 6, suction 1, tcp 3, target 3, tile 3)
    frame = obs[-16:]
    snap = env.unwrapped.sim.snapshot()
    assert np.allclose(frame[10:13], snap["target"]["t"], atol=1e-6)
    assert np.allclose(frame[13:15], [0.2, 0.3], atol=1e-6)
    # a plain reset goes back to the paper's starts
    _, info = env.reset()
    assert info["start"]["object_pose"][1] == pytest.approx(0.32) and info["start"][
        "target_offset"
    ] == (0, 0)


@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"object_pose": [0.9, 0.3, 0.0]}, "object_pose"),
        ({"object_pose": [0.35, 0.42, 0.0]}, "object_pose"),
        ({"object_pose": [-0.2, 0.28, 0.0]}, "object_pose"),
        ({"object_pose": [0.1, 0.3]}, "object_pose"),
        ({"object_pose": [0.1, 0.3, float("nan")]}, "object_pose"),
        ({"object_pose": [0.1, 0.3, 0.0], "target_offset": [0.1, 0.0]}, "target_offset"),
        ({"target_offset": [0.0, 0.0]}, "object_pose"),
    ],
)
def test_bad_reset_options_name_the_field(options, field):
    env = gym.make("mimicrete/TileSuction-v0")
    with pytest.raises(ValueError, match=field):
        env.reset(options=options)


def test_vector_env_takes_one_start_per_env_and_keeps_them_in_its_state():
    v = mc.envs.make_vec("BlockGrip-v0", num_envs=2, seed=0)
    starts = {
        "object_pose": [[0.2, 0.3, 0.1], [0.1, 0.35, -0.2]],
        "target_offset": [[0, 0], [0.04, 0.04]],
    }
    obs, _ = v.reset(seed=3, options=starts)
    st = v.state()
    # x, y, yaw, target dx, dy, pad dx, dy, pad yaw (the pad of BlockGrip is never turned)
    assert np.allclose(st["starts"][1], [0.1, 0.35, -0.2, 0.04, 0.04, 0.04, 0.04, 0.0], atol=1e-6)
    w = mc.envs.make_vec("BlockGrip-v0", num_envs=2, seed=9)
    assert np.array_equal(w.restore(st), obs)
    with pytest.raises(ValueError, match="env 1: object_pose"):
        v.reset(seed=3, options={"object_pose": [[0.2, 0.3, 0.1], [0.9, 0.35, 0.0]]})
    with pytest.raises(ValueError, match="object_pose must be a list of 2 entries"):
        v.reset(seed=3, options={"object_pose": [[0.2, 0.3, 0.1]]})
    v.close()
    w.close()


def test_eval_on_a_starts_file_runs_one_episode_per_line(run_dir, tmp_path):
    f = tmp_path / "site.jsonl"
    f.write_text(
        "# two starts where the demos were, one turned and moved a little\n"
        '{"object_pose": [0.05, 0.32, 0.0]}\n'
        "\n"
        '{"object_pose": [0.10, 0.32, 0.0], "target_offset": [0.0, 0.0]}\n'
        '{"object_pose": [0.12, 0.33, 0.1], "target_offset": [0.01, 0.01]}\n'
    )
    r = run_cli("eval", str(run_dir), "--starts", str(f))
    assert r.returncode == 0, r.stderr
    assert f"starts: file:{f}, 3 episodes" in r.stdout
    res = json.loads((run_dir / "eval_starts-site.json").read_text())
    assert res["episodes"] == 3 and res["starts"] == f"file:{f}" and len(res["starts_sha256"]) == 64
    # the group-3 policy installs from the paper's starts
    assert res["installed_rate"] >= 2 / 3


def test_eval_on_the_wide_starts_says_so(run_dir):
    r = run_cli("eval", str(run_dir), "--starts", "wide", "--episodes", "4")
    assert r.returncode == 0, r.stderr
    res = json.loads((run_dir / "eval_wide.json").read_text())
    assert (res["starts"], res["episodes"]) == ("wide", 4)


@pytest.mark.parametrize(
    ("text", "want"),
    [
        ('{"object_pose": [0.1, 0.32, 0.0]}\nnot json\n', ":2: not a JSON object"),
        ('{"target_offset": [0, 0]}\n', ":1: missing object_pose"),
        ('{"object_pose": [0.1, 0.32]}\n', ":1: object_pose must be a list of 3 numbers"),
        ('{"object_pose": [0.1, 0.32, 0], "yaw": 1}\n', ":1: unknown field 'yaw'"),
        (
            '{"object_pose": [0.1, 0.32, 0], "object_pose": [0.2, 0.3, 0]}\n',
            ":1: not a JSON object (duplicate key",
        ),
        ("[1, 2]\n", ":1: expected a JSON object"),
        ("\n# nothing\n", ": no starts in the file"),
        (
            '\n{"object_pose": [0.35, 0.42, 0.0]}\n',
            ":2: invalid argument: object_pose (0.35, 0.42) m is out of reach: 0.547 m from the "
            "base axis; the UR3 reaches",
        ),
        (
            '{"object_pose": [0.1, 0.32, 0.0], "target_offset": [0.2, 0]}\n',
            ":1: invalid argument: target_offset",
        ),
    ],
)
def test_a_bad_starts_file_is_one_line_naming_file_and_line(run_dir, tmp_path, text, want):
    f = tmp_path / "bad.jsonl"
    f.write_text(text)
    r = run_cli("eval", str(run_dir), "--starts", str(f))
    assert r.returncode == 2, r.stdout + r.stderr
    assert want in r.stderr and str(f) in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not (run_dir / "eval_starts-bad.json").exists()


def test_eval_start_flags_refused(run_dir, tmp_path):
    for args, want in [
        (["--starts", "wide", "--robust"], "--robust and --starts"),
        (["--starts", "everywhere"], "starts: expected training, robust, wide or a FILE.jsonl"),
        (["--starts", str(tmp_path / "missing.jsonl")], "no such starts file"),
    ]:
        r = run_cli("eval", str(run_dir), *args)
        assert r.returncode == 2 and want in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_train_ends_with_the_row_on_the_training_and_the_wide_starts_beside_the_papers(run_dir):
    from mimicrete.cli.train import _eval_rows

    out = _eval_rows(run_dir, 4, "group3", None).splitlines()
    assert out[0].split()[:3] == ["run", "Picked", "rate"] and len(out) == 4 + 2 * 8 + 1
    assert out[1].startswith("run, training starts") and out[2].startswith("run, wide starts")
    assert out[3].split()[-3:] == ["97%", "97%", "90.0"] and "paper, group 3" in out[3]
    # where the tiles ended, on each set of starts (mimicrete eval's placement table)
    assert out[4] == "run, training starts:" and out[5].startswith("placement (4 episodes)")
    assert out[12] == "run, wide starts:" and out[13].startswith("placement (4 episodes)")
    assert out[11].startswith("placed by the placed rule") and out[19].startswith("placed by")
    assert out[20] == f"plot: {run_dir / 'success_map.png'} (installed rate over the tile's " \
        "start x, y; wide starts)"  # fmt: skip
    assert json.loads((run_dir / "eval_wide.json").read_text())["starts"] == "wide"
    # a config that is not one of the paper's groups: no paper row
    assert len(_eval_rows(run_dir, 4, "wide", None).splitlines()) == 4 + 2 * 8


def test_eval_records_each_episodes_start_and_draws_the_map(run_dir):
    r = run_cli("eval", str(run_dir), "--episodes", "6", "--map")
    assert r.returncode == 0, r.stderr
    res = json.loads((run_dir / "eval.json").read_text())
    eps = res["per_episode"]
    assert len(eps) == 6 and np.mean([e["installed"] for e in eps]) == res["installed_rate"]
    assert np.mean([e["length"] for e in eps]) == pytest.approx(res["mean_episode_length"])
    for e in eps:  # the paper's starts: x in [0, 0.15] m at y = 0.32 m, the target fixed
        x, y, yaw = e["object_pose"]
        assert 0 <= x <= 0.15 and y == pytest.approx(0.32) and yaw == 0
        assert e["target_offset"] == [0, 0]
    assert len({e["object_pose"][0] for e in eps}) == 6  # six different draws
    assert (run_dir / "eval_map.png").stat().st_size > 5_000
    assert f"wrote {run_dir / 'eval_map.png'}" in r.stdout
    # a starts file's episodes are recorded at exactly the listed starts
    f = run_dir.parent / "two.jsonl"
    f.write_text('{"object_pose": [0.2, 0.3, 0.2]}\n{"object_pose": [0.1, 0.32, -0.1]}\n')
    r = run_cli("eval", str(run_dir), "--starts", str(f), "--map")
    assert r.returncode == 0, r.stderr
    listed = json.loads((run_dir / "eval_starts-two.json").read_text())["per_episode"]
    assert sorted(e["object_pose"] for e in listed) == [[0.1, 0.32, -0.1], [0.2, 0.3, 0.2]]
    assert (run_dir / "eval_starts-two_map.png").is_file()
