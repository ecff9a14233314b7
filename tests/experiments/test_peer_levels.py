"""The peers' harness on the level layout (issue 44 §1): its datasets carry the suction command as
a level, the adapter maps a policy's level back to the env's command, and a dataset, training or
result of the old one-step-switch layout is never reused as if it were the new one. No lerobot
needed (tests/experiments/test_peers.py runs the whole pipeline in the lerobot venv)."""

from __future__ import annotations

import json

import numpy as np
import pyarrow.parquet as pq
import pytest

from mimicrete import _native
from mimicrete.experiments import peer_adapter, peers
from mimicrete.export import source

NAMES = source.ACTION_NAMES["suction"]
OLD_NAMES = [*NAMES[:6], "suction_command"]


def test_the_harness_dataset_holds_the_suction_level(one_demo, tmp_path):
    root = peers.make_dataset(one_demo, 1, tmp_path)
    assert peers.dataset_layout(root) == "level"
    info = json.loads((root / "meta/info.json").read_text())
    assert info["features"]["action"]["names"][6] == "suction_level"
    data = pq.read_table(root / "data/chunk-000/file-000.parquet")
    level = np.array(data.column("action").to_pylist())[:, 6]
    # off until the pick, on from then: both classes are a large share of the frames
    k = int(np.argmax(level > 0))
    assert 0 < k < len(level) - 1
    assert (level[:k] == -1).all() and (level[k:] == 1).all()
    stats = json.loads((root / "meta/stats.json").read_text())
    assert stats["action"]["std"][6] > 0.3  # a switch would give ~0.06


def test_an_old_layout_dataset_is_refused_naming_it(tmp_path):
    root = tmp_path / "datasets" / "suction-n5"
    (root / "meta").mkdir(parents=True)
    info = {"features": {"action": {"names": OLD_NAMES}}}
    (root / "meta/info.json").write_text(json.dumps(info))
    with pytest.raises(peers.PeersError) as e:
        peers.make_dataset(tmp_path / "no-demos-needed", 5, tmp_path)
    msg = str(e.value)
    assert str(root) in msg and "old action layout" in msg and "'suction_command'" in msg
    assert "delete" in msg and "\n" not in msg
    # through the command: exit 2, one line
    assert peers.main(["run", "--demos", str(tmp_path), "--counts", "5", "--methods", "act",
                       "--lerobot-python", "/bin/true", "--out", str(tmp_path)]) == 2  # fmt: skip


def test_an_old_layout_result_or_training_is_not_reused(tmp_path):
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"steps": 10, "episodes": 4, "action_layout": "switch"}))
    assert not peers._fresh(path, 10, 4, layout="level")
    path.write_text(json.dumps({"steps": 10, "episodes": 4}))  # written before the level
    assert not peers._fresh(path, 10, 4, layout="level")
    path.write_text(json.dumps({"steps": 10, "episodes": 4, "action_layout": "level"}))
    assert peers._fresh(path, 10, 4, layout="level")
    assert not peers._fresh(path, 11, 4, layout="level")


def test_the_adapter_maps_a_policys_level_to_the_env(one_demo):
    """Each action of the demo's level, shrunk towards 0 as a policy's output may be, then through
    the adapter's mapping, steps the env to the demo's end; the old layout passes as it was."""
    from mimicrete import demos
    from mimicrete.export import levels

    ep = demos.read(sorted(one_demo.glob("*.mcap"))[0])
    rec = np.asarray(ep["actions"], np.float32)
    level = levels.to_levels("suction", rec)
    policy = level.copy()
    policy[:, 6] *= np.linspace(0.05, 1.2, len(policy), dtype=np.float32)
    policy[:, :6] *= 1.5  # beyond the action space: clipped
    mapped = peer_adapter.env_actions(policy, NAMES)
    assert set(mapped[:, 6].tolist()) == {-1.0, 1.0}
    assert np.abs(mapped[:, :6]).max() <= 1.0
    env = _native.SimEnv("TileSuction")
    env.reset(int(ep["meta"]["seed"]))
    want = levels.to_env(level, NAMES)
    np.testing.assert_array_equal(mapped[:, 6], want[:, 6])
    for a in np.clip(np.concatenate([rec[:, :6], mapped[:, 6:]], axis=1), -1, 1):
        *_, te, tr, info = env.step(a)
    assert te and info["installed"]
    # the old layout: a switch policy's output is clipped only (0 keeps the suction as it is)
    np.testing.assert_array_equal(peer_adapter.env_actions(rec, OLD_NAMES), np.clip(rec, -1, 1))
    np.testing.assert_array_equal(peer_adapter.env_actions(rec, None), np.clip(rec, -1, 1))
