"""GAE with termination, truncation bootstrap and segment cuts (mimicrete.learn.buffer)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete.learn.buffer import Rollout, gae, horizon_cuts


def test_gae_hand_computed_truncation_and_termination():
    gamma, lam = 0.9, 0.8
    # env 0: truncated at t=1 (bootstrap from V(final_obs) = 0.7), end of rollout at t=3
    # env 1: terminated at t=1 (next value 5.0 must be ignored)
    rewards = np.array([[1, 1], [0, 0], [2, 2], [1, 1]], float)
    values = np.array([[0.5, 0.5], [0.4, 0.4], [0.3, 0.3], [0.2, 0.2]])
    next_values = np.array([[0.4, 0.4], [0.7, 5.0], [0.2, 0.2], [0.6, 0.6]])
    terminated = np.array([[0, 0], [0, 1], [0, 0], [0, 0]], bool)
    cut = np.array([[0, 0], [1, 1], [0, 0], [1, 1]], bool)
    adv, ret = gae(rewards, values, next_values, terminated, cut, gamma, lam)
    # by hand: deltas env0 = 0.86, 0.23, 1.88, 1.34; env1 delta1 = 0 - 0.4 = -0.4
    expected0 = [0.86 + 0.72 * 0.23, 0.23, 1.88 + 0.72 * 1.34, 1.34]
    expected1 = [0.86 + 0.72 * -0.4, -0.4, 1.88 + 0.72 * 1.34, 1.34]
    np.testing.assert_allclose(adv[:, 0], expected0, atol=1e-12)
    np.testing.assert_allclose(adv[:, 1], expected1, atol=1e-12)
    np.testing.assert_allclose(ret, adv + values, atol=1e-12)


def test_truncation_differs_from_termination_only_by_bootstrap():
    r = np.zeros((3, 1))
    v = np.zeros((3, 1))
    nv = np.full((3, 1), 2.0)
    cut = np.array([[0], [0], [1]], bool)
    a_trunc, _ = gae(r, v, nv, np.zeros((3, 1), bool), cut, 0.5, 1.0)
    a_term, _ = gae(r, v, nv, np.array([[0], [0], [1]], bool), cut, 0.5, 1.0)
    assert a_trunc[2, 0] == 1.0 and a_term[2, 0] == 0.0  # gamma * V(final_obs) vs 0
    np.testing.assert_allclose(a_trunc[:, 0] - a_term[:, 0], [0.25, 0.5, 1.0])


def _reference(r, v, nv, term, cut, gamma, lam):
    T, N = r.shape
    out = np.zeros_like(r)
    for n in range(N):
        for t in range(T):
            acc, coef = 0.0, 1.0
            for s in range(t, T):
                delta = r[s, n] + gamma * (0.0 if term[s, n] else nv[s, n]) - v[s, n]
                acc += coef * delta
                if cut[s, n]:
                    break
                coef *= gamma * lam
            out[t, n] = acc
    return out


@settings(max_examples=60, deadline=None)
@given(
    T=st.integers(1, 12),
    N=st.integers(1, 4),
    gamma=st.floats(0.0, 1.0),
    lam=st.floats(0.0, 1.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_gae_matches_per_step_sum(T, N, gamma, lam, seed):
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(T, N))
    v = rng.normal(size=(T, N))
    nv = rng.normal(size=(T, N))
    term = rng.random((T, N)) < 0.2
    cut = term | (rng.random((T, N)) < 0.2)
    cut[-1] = True
    adv, _ = gae(r, v, nv, term, cut, gamma, lam)
    np.testing.assert_allclose(adv, _reference(r, v, nv, term, cut, gamma, lam), atol=1e-9)


def test_horizon_cuts_and_next_obs_uses_final_obs():
    c = horizon_cuts(7, 2, 3)
    assert c[:, 0].tolist() == [False, False, True, False, False, True, True]
    ro = Rollout(3, 2, 4, 6)
    ro.obs[:] = np.arange(3)[:, None, None] + 10 * np.arange(2)[None, :, None]
    ro.last_obs[:] = 99
    ro.truncated[1, 0] = True
    ro.final_obs[1, 0] = -7
    nxt = ro.next_obs()
    assert nxt[0, 0, 0] == 1 and nxt[1, 0, 0] == -7 and nxt[1, 1, 0] == 12
    assert (nxt[2] == 99).all()


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_values_and_next_match_the_critic_on_the_true_next_observations(seed):
    """One critic pass over the distinct observations gives what two full passes (every
    observation, every true next observation) give, endings and the last step included."""
    import torch

    from mimicrete.learn.buffer import Rollout
    from mimicrete.learn.networks import Critic

    rng = np.random.default_rng(seed)
    T, N, D = 40, 6, 9
    ro = Rollout(T, N, D, 6)
    ro.obs[:] = rng.normal(size=ro.obs.shape)
    ro.last_obs[:] = rng.normal(size=(N, D))
    ro.final_obs[:] = rng.normal(size=ro.final_obs.shape)
    ro.terminated[:] = rng.random((T, N)) < 0.05
    ro.truncated[:] = rng.random((T, N)) < 0.05
    ro.truncated[-1, 0] = True  # an episode ending at the rollout's last step
    critic = Critic(D, 2, 32, 2, normalize=True)
    calls = []

    def value_fn(x):
        calls.append(len(x))
        with torch.no_grad():
            return critic(torch.from_numpy(x)).numpy()

    values, nxt = ro.values_and_next(value_fn)
    assert calls == [T * N + N + int(ro.ended.sum())]
    with torch.no_grad():
        v0 = critic(torch.from_numpy(ro.obs.reshape(-1, D))).numpy().reshape(T, N, 2)
        n0 = critic(torch.from_numpy(ro.next_obs().reshape(-1, D))).numpy().reshape(T, N, 2)
    np.testing.assert_allclose(values, v0, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(nxt, n0, rtol=1e-6, atol=1e-6)
