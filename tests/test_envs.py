"""Gymnasium envs over the Rust simulator: checker, vector API, seeding, errors, SB3, rendering."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mimicrete
from mimicrete import _native

if not hasattr(_native, "SimEnv"):  # pragma: no cover - depends on how the module was built
    pytest.fail(
        "mimicrete._native was built without the tile-sim bindings "
        "(crates/pyext needs the `tile-sim` dependency/feature)",
        pytrace=False,
    )

from gymnasium.utils.env_checker import check_env  # noqa: E402

import mimicrete.envs as E  # noqa: E402


@pytest.mark.parametrize("env_id", E.ENV_IDS)
def test_env_checker_passes(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    assert env.spec is not None and env.spec.max_episode_steps is None  # the sim truncates
    obs, info = env.reset(seed=0)
    assert obs.dtype == np.float32 and obs.shape == env.observation_space.shape
    assert env.action_space.shape == ((8,) if "Screw" in env_id else (7,))
    env.close()


def test_dims_match_the_contract() -> None:
    c = _native.sim_constants()
    assert c["FRAME_STACK"] == 5 and c["MAX_EPISODE_STEPS"] == 750
    assert c["CONTROL_DT"] == pytest.approx(0.04) and c["MAX_JOINT_STEP"] == pytest.approx(0.04)
    assert c["PICK_DIST"] == 0.04 and c["INSTALL_DIST"] == 0.03
    for task, dims in c["tasks"].items():
        assert dims["obs_dim"] == 5 * dims["obs_frame_dim"]
        env = E.MimicreteEnv(task)
        assert env.observation_space.shape == (dims["obs_dim"],)


def test_reset_zero_pads_and_newest_frame_last() -> None:
    env = gym.make("mimicrete/TileSuction-v0")
    obs, _ = env.reset(seed=3)
    assert np.all(obs[:64] == 0.0)
    frame = obs[64:]
    np.testing.assert_allclose(frame[:6], _native.sim_constants()["HOME_Q"], atol=1e-6)
    assert frame[6] == -1.0  # suction off
    assert 0.0 <= frame[13] <= 0.15  # tile x
    a = np.zeros(7, np.float32)
    a[0] = 1.0
    obs2, r, term, trunc, info = env.step(a)
    assert np.all(obs2[:48] == 0.0) and np.array_equal(obs2[48:64], frame)
    assert obs2[64] == pytest.approx(frame[0] + 0.04, abs=1e-6)
    assert r == 0.0 and not term and not trunc
    assert set(info) >= {"picked", "installed", "fell", "held"}


def _rollout(env: gym.Env, seed: int, n: int) -> np.ndarray:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [obs]
    for _ in range(n):
        obs, r, term, trunc, _ = env.step(
            rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
        )
        out.append(np.append(obs, r))
        if term or trunc:
            obs, _ = env.reset()
    return np.concatenate(out)


def test_determinism_from_python() -> None:
    for env_id in E.ENV_IDS:
        a = _rollout(gym.make(env_id), 11, 300)
        b = _rollout(gym.make(env_id), 11, 300)
        assert a.tobytes() == b.tobytes()
        c = _rollout(gym.make(env_id), 12, 300)
        assert a.tobytes() != c.tobytes()


def test_vector_env_api_and_same_step_autoreset() -> None:
    n = 4
    venv = E.make_vec("TileSuction-v0", n, seed=5)
    assert isinstance(venv, gym.vector.VectorEnv)
    assert venv.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    assert venv.observation_space.shape == (n, 80) and venv.action_space.shape == (n, 7)
    obs, _ = venv.reset(seed=5)
    assert obs.shape == (n, 80) and obs.dtype == np.float32
    # Env i of the vector env == a single native env reset with seed 5 + i.
    single = _native.SimEnv("TileSuction", 0)
    np.testing.assert_array_equal(single.reset(7), obs[2])
    zeros = np.zeros((n, 7), np.float32)
    for k in range(1, 751):
        obs, rew, term, trunc, infos = venv.step(zeros)
        if k < 750:
            assert not trunc.any() and "final_obs" not in infos
    assert trunc.all() and not term.any()
    assert infos["_final_obs"].all() and infos["final_obs"].dtype == object
    for i in range(n):
        fin = infos["final_obs"][i]
        assert fin.shape == (80,) and not np.all(fin[:64] == 0.0)  # a full 5-frame history
        assert np.all(obs[i, :64] == 0.0)  # the new episode's first obs, zero padded
    assert set(infos["final_info"]) >= {"picked", "_picked", "installed", "fell"}
    assert infos["_final_info"].all()
    # The step after the auto-reset continues normally.
    obs, rew, term, trunc, infos = venv.step(zeros)
    assert not trunc.any() and np.all(obs[:, :48] == 0.0)


def test_vector_env_final_obs_only_for_done_rows() -> None:
    venv = E.make_vec("mimicrete/TileSuction-v0", 3, seed=0)
    venv.reset(seed=0)
    # Step env 1 ten more times than the others by resetting the others midway.
    zeros = np.zeros((3, 7), np.float32)
    for _ in range(10):
        venv.step(zeros)
    venv.reset(options={"reset_mask": np.array([True, False, True])})
    for _ in range(740):
        obs, _, _, trunc, infos = venv.step(zeros)
    assert trunc.tolist() == [False, True, False]
    assert infos["_final_obs"].tolist() == [False, True, False]
    assert infos["final_obs"][0] is None and infos["final_obs"][1] is not None


def test_reset_mask_resets_only_masked_envs() -> None:
    venv = E.make_vec("TileSuction-v0", 3, seed=1)
    obs0, _ = venv.reset(seed=1)
    a = np.zeros((3, 7), np.float32)
    a[:, 0] = 1.0
    obs1, *_ = venv.step(a)
    obs2, _ = venv.reset(options={"reset_mask": np.array([False, True, False])})
    np.testing.assert_array_equal(obs2[0], obs1[0])
    np.testing.assert_array_equal(obs2[2], obs1[2])
    assert np.all(obs2[1, :64] == 0.0) and obs2[1, 64] == pytest.approx(obs0[1, 64])
    with pytest.raises(ValueError, match=r"reset_mask must have shape \(3,\)"):
        venv.reset(options={"reset_mask": np.array([True, False])})


def test_vector_seeding() -> None:
    def run(seed: int) -> np.ndarray:
        venv = E.make_vec("BlockGrip-v0", 3, seed=seed)
        obs, _ = venv.reset(seed=seed)
        rng = np.random.default_rng(0)
        out = [obs]
        for _ in range(50):
            obs, r, *_ = venv.step(rng.uniform(-1, 1, (3, 7)).astype(np.float32))
            out += [obs, r[:, None]]
        return np.concatenate([o.reshape(3, -1) for o in out], axis=1)

    assert run(4).tobytes() == run(4).tobytes()
    assert run(4).tobytes() != run(5).tobytes()
    venv = E.make_vec("TileSuction-v0", 3)
    o_list, _ = venv.reset(seed=[8, 9, 10])
    o_int, _ = venv.reset(seed=8)
    np.testing.assert_array_equal(o_list, o_int)
    with pytest.raises(ValueError, match="consecutive"):
        venv.reset(seed=[1, 5, 2])


def test_gymnasium_make_vec_entry_point() -> None:
    venv = gym.make_vec("mimicrete/Screw-v0", num_envs=2, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=0)
    assert obs.shape == (2, 90)


def test_error_messages() -> None:
    env = gym.make("mimicrete/TileSuction-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(7,\)"):
        env.step(np.zeros(6, np.float32))
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.full(7, np.nan, np.float32))
    raw = _native.SimEnv("TileSuction", 0)
    raw.reset(0)
    with pytest.raises(ValueError, match=r"action must have shape \(7,\), got \(2, 7\)"):
        raw.step(np.zeros((2, 7)))
    with pytest.raises(ValueError, match="not finite"):
        raw.step(np.array([0, 0, 0, np.nan, 0, 0, 0], np.float32))
    venv = _native.SimVecEnv("TileSuction", 4, 0, 2)
    with pytest.raises(ValueError, match=r"actions must have shape \(4, 7\), got \(4, 8\)"):
        venv.step(np.zeros((4, 8), np.float32))
    with pytest.raises(ValueError, match="unknown task"):
        _native.SimEnv("Welding", 0)
    with pytest.raises(ValueError, match="unknown env id"):
        E.make_vec("mimicrete/Welding-v0", 2)
    # Stepping an episode that has ended is a SimError.
    raw.set_object_pose([0.9, 0.0, 0.05], [0.0, 0.0, 0.0, 1.0])
    for _ in range(50):
        _, r, term, trunc, _ = raw.step(np.zeros(7, np.float32))
        if term:
            assert r == -0.5
            break
    with pytest.raises(mimicrete.SimError, match="reset"):
        raw.step(np.zeros(7, np.float32))


def test_scripted_expert_through_python() -> None:
    env = gym.make("mimicrete/TileSuction-v0")
    sim = env.unwrapped.sim
    expert = _native.SimExpert("TileSuction")
    installed = 0
    for seed in range(10):
        env.reset(seed=seed)
        expert.reset()
        total = 0.0
        for _ in range(750):
            obs, r, term, trunc, info = env.step(expert.act(sim))
            total += r
            if term or trunc:
                break
        installed += int(info["installed"])
        assert total == (2.0 if info["installed"] else total)
    assert installed == 10


def test_render_rgb_array_shows_the_motion() -> None:
    env = gym.make("mimicrete/TileSuction-v0", render_mode="rgb_array")
    env.reset(seed=0)
    img0 = env.render()
    assert img0.dtype == np.uint8 and img0.ndim == 3 and img0.shape[2] == 3
    a = np.zeros(7, np.float32)
    a[0] = 1.0
    for _ in range(20):
        env.step(a)
    img1 = env.render()
    assert img1.shape == img0.shape and np.abs(img1.astype(int) - img0.astype(int)).sum() > 1000
    plain = gym.make("mimicrete/TileSuction-v0")
    plain.reset(seed=0)
    assert plain.render() is None


def test_short_sb3_ppo_run() -> None:
    sb3 = pytest.importorskip("stable_baselines3")
    env = gym.make("mimicrete/TileSuction-v0")
    model = sb3.PPO("MlpPolicy", env, n_steps=128, batch_size=64, n_epochs=2, seed=0, device="cpu")
    model.learn(total_timesteps=256)
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (7,)
    env.step(action)


def _vec_log(venv: E.MimicreteVecEnv, steps: int, act_seed: int) -> tuple[bytes, int]:
    """Obs, rewards, flags and terminal rows of `steps` random steps, as bytes; episode ends."""
    rng = np.random.default_rng(act_seed)
    n = venv.num_envs
    out, ends = [], 0
    for _ in range(steps):
        obs, r, term, trunc, infos = venv.step(rng.uniform(-1, 1, (n, 7)).astype(np.float32))
        out += [obs.tobytes(), r.tobytes(), term.tobytes(), trunc.tobytes()]
        if "final_obs" in infos:
            for i in np.flatnonzero(infos["_final_obs"]):
                ends += 1
                out.append(np.asarray(infos["final_obs"][i]).tobytes())
    return b"".join(out), ends


def test_vector_reset_seed_fixes_auto_reset_episodes() -> None:
    """gymnasium's contract across auto-resets: two fresh vector envs reset with the same seed
    give identical trajectories through their auto-resets, and a used env reset with seed s
    equals a fresh one reset with s."""
    steps = 1600  # two truncations per env
    fresh1 = E.make_vec("TileSuction-v0", 2, seed=3)
    fresh2 = E.make_vec("TileSuction-v0", 2, seed=99)
    o1, _ = fresh1.reset(seed=42)
    o2, _ = fresh2.reset(seed=42)
    np.testing.assert_array_equal(o1, o2)
    log1, ends = _vec_log(fresh1, steps, 0)
    log2, _ = _vec_log(fresh2, steps, 0)
    assert ends >= 4 and log1 == log2
    # fresh1 is now used (several auto-resets, a masked reset): reset with 42 starts over.
    fresh1.reset(options={"reset_mask": np.array([True, False])})
    o3, _ = fresh1.reset(seed=42)
    np.testing.assert_array_equal(o3, o1)
    log3, _ = _vec_log(fresh1, steps, 0)
    assert log3 == log1
    # and the auto-reset episodes do depend on the seed
    fresh2.reset(seed=43)
    assert _vec_log(fresh2, steps, 0)[0] != log1


def test_vector_state_restore_is_exact() -> None:
    venv = E.make_vec("TileSuction-v0", 3, seed=5)
    venv.reset(seed=5)
    _vec_log(venv, 900, 1)  # one auto-reset per env, then 150 steps into the next episode
    st = venv.state()
    assert [len(a) for a in st["actions"]] == [150, 150, 150]
    assert list(st["episodes"]) == [1, 1, 1] and st["base_seed"] == 5
    other = E.make_vec("TileSuction-v0", 3, seed=77)
    obs = other.restore(st)
    assert obs.shape == (3, 80)
    a, _ = _vec_log(venv, 800, 2)
    b, _ = _vec_log(other, 800, 2)
    assert a == b
    bad = dict(st, episodes=[1, 1])
    with pytest.raises(ValueError, match="episodes buffer has length 2, expected 3"):
        other.restore(bad)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"seed": -1}, r"seed must be an integer in \[0, 2\*\*64-1\], got -1"),
        ({"seed": 2**64}, r"seed must be an integer in \[0, 2\*\*64-1\], got 18446744073709551616"),
        ({"seed": 1.5}, r"seed must be an integer in \[0, 2\*\*64-1\], got 1.5 \(float\)"),
        ({"num_envs": 2.7}, r"num_envs must be a positive integer, got 2.7 \(float\)"),
        ({"num_envs": 0}, r"num_envs must be at least 1, got 0"),
        ({"num_envs": True}, r"num_envs must be a positive integer, got True"),
        ({"num_threads": 0}, r"num_threads must be at least 1, got 0"),
    ],
)
def test_make_vec_refuses_bad_numbers(kwargs: dict, message: str) -> None:
    args = {"num_envs": 2, "seed": 0} | kwargs
    with pytest.raises(ValueError, match=message):
        E.make_vec("TileSuction-v0", **args)


def test_make_vec_accepts_the_whole_seed_range() -> None:
    for s in (0, np.uint64(2**64 - 1), np.int64(7), 2**64 - 1):
        venv = E.make_vec("TileSuction-v0", 2, seed=s)
        obs, _ = venv.reset(seed=s)
        assert obs.shape == (2, 80)
    with pytest.raises(ValueError, match=r"seed must be an integer in \[0, 2\*\*64-1\], got -3"):
        venv.reset(seed=-3)
