"""Generated demos export (``mimicrete demogen`` → ``mimicrete export``): a generated demo starts
at the explicit start its metadata records, not at its seed's own start, and the export replays
it from there, as the demo curriculum does. Every exported episode, started from the dataset's
stored seed and start, gives back its demo step for step and ends as the demo did."""

from __future__ import annotations

import json
import os

import numpy as np
import pyarrow.parquet as pq
import pytest

from mimicrete import _native
from mimicrete.cli import main as cli_main
from mimicrete.export import source

#: generated demos exported (the test's run time goes with it)
COUNT = 4


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """``COUNT`` TilePlace demos that ``mimicrete demogen`` (the CLI) made at wide starts (a
    turned pad) from 2 scripted demos (real hand logs through the real converter, as the other
    export tests make them)."""
    from mimicrete import demonstrator as synth
    from mimicrete.teleop import convert

    root = tmp_path_factory.mktemp("generated")
    src = root / "sources"
    src.mkdir()
    for i, p in enumerate(synth.synth_hands("place", 2, 3, root / "hands")):
        convert.convert_log(p, "place", src, episode_index=i)
    out = root / "gen"
    args = ["demogen", "--demos", str(src), "--count", str(COUNT), "--out", str(out)]
    assert cli_main([*args, "--seed", "1", "--no-progress"]) == 0
    assert len(list(out.glob("*.mcap"))) == COUNT
    return out


def test_a_generated_demo_does_not_start_at_its_seeds_start(generated):
    """Without its recorded start the replay fails at step 0 (what the export did before)."""
    ds = source.read_demo_dir(generated)
    assert len(ds.episodes) == COUNT
    for ep in ds.episodes:
        assert ep.start is not None and "pad_yaw" in ep.start, ep.meta
        assert ep.start["object_pose"] == json.loads(ep.meta["object_pose"])
        o = np.asarray(_native.SimEnv(ds.sim, 0).reset(ep.seed), np.float32)
        assert not np.array_equal(o, ep.obs[0])
        with pytest.raises(source.ExportError, match="from seed .* at step 0"):
            source._replay(generated / "x", ds.sim, ep.seed, ep.obs, ep.recorded_actions,
                           {"rewards": ep.rewards, "terminated": ep.terminated,
                            "truncated": ep.truncated})  # fmt: skip


def test_generated_demos_export_and_replay_to_their_outcome(generated, tmp_path):
    lr, mn = tmp_path / "lerobot", tmp_path / "minari"
    assert cli_main(["export", str(generated), "--format", "lerobot", "--out", str(lr)]) == 0
    assert cli_main(["export", str(generated), "--format", "minari", "--out", str(mn)]) == 0
    ds = source.read_demo_dir(generated)

    # LeRobot: each episode row holds the start as JSON beside the seed
    rows = pq.read_table(lr / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert [json.loads(r["mimicrete/start"]) for r in rows] == [e.start for e in ds.episodes]
    assert [r["mimicrete/seed"] for r in rows] == [e.seed for e in ds.episodes]

    # Minari: the stored reset options start each episode; its actions give back its
    # observations, rewards and ends, and the last step installs as the demo did
    import minari

    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(mn)
    try:
        data = minari.load_dataset("mimicrete/TilePlace/demos-v0")
        env = data.recover_environment()
        installed = []
        for ep, meta in zip(
            data.iterate_episodes(), data.storage.get_episode_metadata(range(COUNT)), strict=True
        ):
            demo = ds.episodes[ep.id]
            assert meta["options"] == {"episode_seed": demo.seed, **demo.start}
            o, _ = env.reset(options=meta["options"])
            np.testing.assert_array_equal(o, ep.observations[0])
            for k, a in enumerate(ep.actions):
                o, r, te, tr, info = env.step(a)
                np.testing.assert_array_equal(o, ep.observations[k + 1])
                assert (np.float32(r), te, tr) == (
                    np.float32(ep.rewards[k]),
                    ep.terminations[k],
                    ep.truncations[k],
                )
            assert bool(info["installed"]) == demo.success
            installed.append(bool(info["installed"]))
        env.close()
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old
    assert all(installed)  # demogen keeps only the episodes that install
