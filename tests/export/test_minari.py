"""`mimicrete export --format minari`: loaded by minari.load_dataset; N + 1 observations per
episode, the last one replayed; recover_environment gives our env, which replays each episode
from the stored reset options."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from mimicrete import _native, demos
from mimicrete.cli import main as cli_main

from ._levels import expected_actions


def _load(root, monkeypatch, dataset_id="mimicrete/TileSuction/demos-v0"):
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return minari.load_dataset(dataset_id)


def test_reset_option_starts_the_seeded_episode():
    import mimicrete.envs  # noqa: F401

    env = gym.make("mimicrete/TileSuction-v0")
    sim = _native.SimEnv("TileSuction")
    for seed in (0, 7, 2**63 + 5):
        obs, _ = env.reset(options={"episode_seed": seed})
        np.testing.assert_array_equal(obs, sim.reset(seed))
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3, options={"episode_seed": None})
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="u64"):
        env.reset(options={"episode_seed": -1})


def _check(ds, d, env_replay_episodes):
    slices = d.episode_slices()
    assert ds.total_episodes == len(slices)
    assert ds.total_steps == len(d)
    assert ds.spec.env_spec.id == "mimicrete/TileSuction-v0"
    assert ds.observation_space.shape == (80,) and ds.action_space.shape == (7,)
    eps = list(ds.iterate_episodes())
    actions = expected_actions(d)  # the suction command as a level
    np.testing.assert_array_equal(eps[0].actions[0], actions[0])
    np.testing.assert_array_equal(eps[-1].actions[-1], actions[-1])
    assert ds.storage.metadata["mimicrete_action_layout"] == "level"
    assert ds.storage.metadata["mimicrete_action_names"][6] == "suction_level"
    metas = list(ds.storage.get_episode_metadata(range(len(slices))))
    env = ds.recover_environment()
    assert type(env.unwrapped).__name__ == "TileSuctionEnv"
    for i, (ep, s, meta, m) in enumerate(zip(eps, slices, metas, d.metas, strict=True)):
        n = s.stop - s.start
        assert len(ep) == n and ep.observations.shape == (n + 1, 80)
        np.testing.assert_array_equal(ep.observations[:n], d.obs[s])
        np.testing.assert_array_equal(ep.actions, actions[s])
        np.testing.assert_array_equal(ep.rewards, d.rewards[s])
        np.testing.assert_array_equal(ep.terminations, d.terminated[s])
        assert meta["options"] == {"episode_seed": int(m["seed"])}
        assert meta["success"] == (m["success"] == "true")
        assert ep.infos["installed"].shape == (n + 1,)
        assert bool(ep.infos["installed"][-1]) == (m["success"] == "true")
        assert not ep.infos["picked"][0]
        if i < env_replay_episodes:
            obs, _ = env.reset(options=meta["options"])
            np.testing.assert_array_equal(obs, ep.observations[0])
            for k, a in enumerate(ep.actions):
                obs, r, term, trunc, _ = env.step(a)
                np.testing.assert_array_equal(obs, ep.observations[k + 1])
                assert r == ep.rewards[k] and term == ep.terminations[k]


def test_three_demos(demos3, tmp_path, monkeypatch):
    out = tmp_path / "mn"
    assert cli_main(["export", str(demos3), "--format", "minari", "--out", str(out)]) == 0
    _check(_load(out, monkeypatch), demos.load(demos3), env_replay_episodes=3)


def test_dataset_id_flag(demos3, tmp_path, monkeypatch):
    out = tmp_path / "mn"
    args = ["export", str(demos3), "--format", "minari", "--out", str(out)]
    assert cli_main([*args, "--dataset-id", "lab/suction-v2", "--author", "A. Person"]) == 0
    ds = _load(out, monkeypatch, "lab/suction-v2")
    assert ds.total_episodes == 3 and ds.storage.metadata["author"] == {"A. Person"}


@pytest.mark.slow
def test_minari_loads_60_demos(demos60, tmp_path, monkeypatch):
    out = tmp_path / "mn60"
    assert cli_main(["export", str(demos60), "--format", "minari", "--out", str(out)]) == 0
    _check(_load(out, monkeypatch), demos.load(demos60), env_replay_episodes=60)
