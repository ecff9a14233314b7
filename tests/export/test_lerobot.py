"""`mimicrete export --format lerobot`: the files read back with pyarrow (everywhere), and with
lerobot 0.4.4's own LeRobotDataset in the test venv .venv-export (a subprocess: lerobot's pins
clash with ours; `make export-venv` makes it)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from mimicrete import demos, tasks
from mimicrete.cli import main as cli_main
from mimicrete.export import lerobot as lr

from ._levels import expected_actions

REPO = Path(__file__).resolve().parents[2]
PROBE = Path(__file__).with_name("lerobot_probe.py")
LEROBOT_PY = Path(os.environ.get("MIMICRETE_LEROBOT_PYTHON", REPO / ".venv-export/bin/python"))


def _export(src: Path, out: Path) -> None:
    assert cli_main(["export", str(src), "--format", "lerobot", "--out", str(out)]) == 0


def test_files_match_the_demos(demos3, tmp_path):
    out = tmp_path / "lr"
    _export(demos3, out)
    d = demos.load(demos3)
    info = json.loads((out / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    assert info["fps"] == 25  # 1 / control_dt 0.04
    assert info["total_frames"] == len(d) and info["total_episodes"] == 3
    assert info["features"]["observation.state"]["shape"] == [80]
    assert len(info["features"]["observation.state"]["names"]) == 80
    assert info["features"]["observation.state"]["names"][-1] == "t.tile_z"
    assert info["features"]["action"]["shape"] == [7]

    data = pq.read_table(out / "data/chunk-000/file-000.parquet")
    assert data.num_rows == len(d)
    state = np.stack(data.column("observation.state").to_pylist()).astype(np.float32)
    action = np.stack(data.column("action").to_pylist()).astype(np.float32)
    np.testing.assert_array_equal(state, d.obs)
    # the demo's actions, the suction command as a level (its switches held)
    np.testing.assert_array_equal(action, expected_actions(d))
    assert info["features"]["action"]["names"][-1] == "suction_level"
    np.testing.assert_array_equal(data.column("next.reward").to_numpy(), d.rewards)
    np.testing.assert_array_equal(data.column("episode_index").to_numpy(), d.episode)
    np.testing.assert_array_equal(data.column("index").to_numpy(), np.arange(len(d)))
    ts = data.column("timestamp").to_numpy()
    fi = data.column("frame_index").to_numpy()
    np.testing.assert_allclose(ts, fi / 25.0, rtol=0, atol=1e-6)
    done = data.column("next.done").to_numpy(zero_copy_only=False)
    ends = [s.stop - 1 for s in d.episode_slices()]
    assert np.flatnonzero(done).tolist() == ends
    success = data.column("next.success").to_numpy(zero_copy_only=False)
    for s, m in zip(d.episode_slices(), d.metas, strict=True):
        # success (installed) switches on at the episode's last step, and only then
        assert success[s].tolist() == [False] * (s.stop - s.start - 1) + [m["success"] == "true"]

    eps = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert [e["length"] for e in eps] == [s.stop - s.start for s in d.episode_slices()]
    assert [e["mimicrete/seed"] for e in eps] == [int(m["seed"]) for m in d.metas]
    assert [e["mimicrete/source_demo"] for e in eps] == [Path(f).name for f in d.files]
    assert eps[0]["tasks"] == [tasks.get("suction").instruction]
    assert eps[1]["dataset_from_index"] == eps[0]["dataset_to_index"]
    n0 = eps[0]["length"]
    mean0 = expected_actions(d)[:n0].astype(np.float64).mean(0)
    np.testing.assert_allclose(eps[0]["stats/action/mean"], mean0)

    stats = json.loads((out / "meta/stats.json").read_text())
    np.testing.assert_allclose(stats["observation.state"]["max"], d.obs.max(0), rtol=1e-6)
    assert stats["action"]["count"] == [len(d)]
    rows = pq.read_table(out / "meta/tasks.parquet").to_pylist()
    assert rows == [{"task_index": 0, "task": tasks.get("suction").instruction}]


def test_stats_quantiles():
    v = np.arange(101, dtype=np.float32)
    s = lr._stats(v)
    assert s["q50"].tolist() == [50.0] and s["q01"].tolist() == [1.0]
    assert s["min"].shape == (1,) and s["count"].tolist() == [101]


@pytest.mark.slow
def test_lerobot_loads_60_demos(demos60, tmp_path):
    if not LEROBOT_PY.exists():
        pytest.fail(f"{LEROBOT_PY} missing: run `make export-venv` (lerobot 0.4.4, test-only)")
    out = tmp_path / "lr60"
    _export(demos60, out)
    d = demos.load(demos60)
    env = {**os.environ, "HF_HUB_OFFLINE": "1", "HF_HOME": str(tmp_path / "hf")}
    env.pop("PYTHONPATH", None)  # nothing of ours in lerobot's interpreter
    r = subprocess.run(
        [str(LEROBOT_PY), str(PROBE), str(out)],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    slices = d.episode_slices()
    actions = expected_actions(d)  # the suction command as a level
    assert got["codebase_version"] == "v3.0"
    assert got["num_frames"] == len(d) == sum(s.stop - s.start for s in slices)
    assert got["num_episodes"] == 60
    assert got["fps"] == 25
    np.testing.assert_array_equal(np.float32(got["first_action"]), actions[0])
    np.testing.assert_array_equal(np.float32(got["last_action"]), actions[-1])
    np.testing.assert_array_equal(np.float32(got["first_state"]), d.obs[0])
    assert got["first_task"] == tasks.get("suction").instruction
    last_len = slices[-1].stop - slices[-1].start
    assert got["last_frame_index"] == last_len - 1
    assert got["last_timestamp"] == pytest.approx((last_len - 1) / 25, abs=1e-4)
    assert got["episode_lengths"] == [s.stop - s.start for s in slices]
    assert all(got["done_at_ends"])
    assert got["success_at_ends"] == [m["success"] == "true" for m in d.metas]
    assert got["episode0_seed"] == int(d.metas[0]["seed"])
    assert got["episode0_source_demo"] == Path(d.files[0]).name
    # at an episode's last frame the two later actions are padding, not the next episode's
    assert got["chunk_at_end_pad"] == [False, True, True]
    end0 = actions[slices[0].stop - 1]
    np.testing.assert_array_equal(np.float32(got["chunk_at_end_action0"]), end0)
    np.testing.assert_allclose(
        got["stats_action_mean"], actions.astype(np.float64).mean(0), rtol=1e-9, atol=1e-12
    )
    assert sys.executable != str(LEROBOT_PY)


def test_every_task_has_a_name_for_each_observation_and_action_float():
    from mimicrete.export.source import ACTION_NAMES, FRAME_NAMES

    for name in tasks.TASKS:
        t = tasks.get(name)
        assert len(FRAME_NAMES[name]) == t.obs_frame_dim, name
        assert len(set(FRAME_NAMES[name])) == t.obs_frame_dim, name
        assert len(ACTION_NAMES[name]) == t.act_dim, name
