"""GAIL: reward sign and shape, gradient penalty value, discriminator learning, survivor bias."""

import math

import numpy as np
import pytest
import torch

from mimicrete.learn.buffer import gae
from mimicrete.learn.gail import (
    GRADIENT_PENALTY_WEIGHT,
    Discriminator,
    Gail,
    discriminator_loss,
    gail_reward,
    signal_terminated,
)


def test_reward_is_minus_log_one_minus_d_nonnegative_and_increasing():
    d = torch.linspace(0.0, 1.0, 101, dtype=torch.float64)
    r = gail_reward(d)
    assert (r >= 0).all()
    assert (r[1:] > r[:-1]).all()
    assert r[0] == 0.0
    assert r[50].item() == pytest.approx(math.log(2.0), rel=1e-6)
    assert r[-1].item() == pytest.approx(-math.log(1e-7), rel=1e-6)  # finite at D = 1


def test_gradient_penalty_equals_finite_difference_norm():
    torch.manual_seed(1)
    dim, b = 4, 6
    disc = Discriminator(torch.zeros(dim), torch.ones(dim), hidden=8, layers=2).double()
    expert = torch.randn(b, dim, dtype=torch.float64)
    policy = torch.randn(b, dim, dtype=torch.float64) + 1.0
    torch.manual_seed(123)
    _, stats = discriminator_loss(disc, expert, policy)
    torch.manual_seed(123)
    alpha = torch.rand(b, 1, dtype=torch.float64)
    x_hat = alpha * expert + (1 - alpha) * policy
    h = 1e-6
    norms = []
    with torch.no_grad():
        for i in range(b):
            g = []
            for j in range(dim):
                e = torch.zeros(dim, dtype=torch.float64)
                e[j] = h
                g.append((disc(x_hat[i : i + 1] + e) - disc(x_hat[i : i + 1] - e)).item() / (2 * h))
            norms.append(np.linalg.norm(g))
    expected = float(np.mean((np.array(norms) - 1.0) ** 2))
    assert stats["grad_penalty"] == pytest.approx(expected, rel=1e-5)
    d_e, d_p = disc(expert), disc(policy)
    bce = -(torch.log(d_e + 1e-7) + torch.log(1 - d_p + 1e-7)).mean().item()
    assert stats["loss"] == pytest.approx(bce, rel=1e-9)
    assert GRADIENT_PENALTY_WEIGHT == 10.0


def test_discriminator_learns_expert_from_policy():
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    expert = rng.normal(1.0, 0.5, (2000, 6)).astype(np.float32)
    g = Gail(expert, hidden=32, layers=2, lr=1e-3)
    for _ in range(300):
        pol = torch.from_numpy(rng.normal(-1.0, 0.5, (128, 6)).astype(np.float32))
        stats = g.update(pol, rng)
    # the gradient penalty keeps D smooth, so the estimates separate but do not saturate
    assert stats["expert_estimate"] > 0.7 and stats["policy_estimate"] < 0.35
    r_exp = g.rewards(torch.from_numpy(expert[:200])).mean()
    r_pol = g.rewards(torch.from_numpy(rng.normal(-1.0, 0.5, (200, 6)).astype(np.float32))).mean()
    assert r_exp > 1.0 and 0.0 <= r_pol < 0.45


def test_survivor_bias_handling_removes_the_termination_penalty():
    # a constant positive GAIL reward c and an exact value V = c / (1 - gamma) everywhere:
    # terminating (e.g. installing the tile) is then a loss of -gamma V under "none",
    # and a non-event under "bootstrap".
    gamma, c = 0.99, 0.69
    v = c / (1 - gamma)
    r = np.full((5, 1), c)
    values = np.full((5, 1), v)
    nv = np.full((5, 1), v)
    term = np.zeros((5, 1), bool)
    term[2] = True
    cut = term.copy()
    cut[-1] = True
    a_none, _ = gae(r, values, nv, signal_terminated(term, "none"), cut, gamma, 0.95)
    a_boot, _ = gae(r, values, nv, signal_terminated(term, "bootstrap"), cut, gamma, 0.95)
    assert a_none[2, 0] == pytest.approx(-gamma * v)
    np.testing.assert_allclose(a_boot, 0.0, atol=1e-9)
    with pytest.raises(ValueError):
        signal_terminated(term, "other")


def test_overlapped_gail_steps_give_the_same_training_bit_for_bit(tmp_path):
    """``torch_settings.overlap_gail`` runs the discriminator steps on a second thread beside PPO
    and BC; the draws are taken in the sequential order, so every weight, optimiser state and
    logged scalar equals the sequential run's exactly (and the overlap did run on another
    thread)."""
    import threading

    from mimicrete.learn import config as config_mod
    from mimicrete.learn.trainer import Trainer
    from mimicrete.testing.toyenv import toy_config

    states = {}
    for overlap in (False, True):
        torch.manual_seed(0)
        cfg = config_mod.with_overrides(
            toy_config(tmp_path, gail=0.05, bc=0.5, seed=4),
            [f"torch_settings.overlap_gail={str(overlap).lower()}"],
        )
        tr = Trainer(cfg, tmp_path / f"run-{overlap}", None, 100_000)
        threads: set[str] = set()
        step = tr.state.gail.step

        def spy(*a, _step=step, _seen=threads, **k):
            _seen.add(threading.current_thread().name)
            return _step(*a, **k)

        tr.state.gail.step = spy
        for _ in range(3):
            tr.iterate()
        assert (threading.main_thread().name in threads) is not overlap
        states[overlap] = (
            [p.detach().clone() for p in tr.state.actor.parameters()]
            + [p.detach().clone() for p in tr.state.critic.parameters()]
            + [p.detach().clone() for p in tr.state.gail.disc.parameters()],
            {k: list(v) for k, v in tr.state.pending.update_stats.items()},
            tr.state.rng.bit_generator.state,
            torch.get_rng_state(),
        )
        tr.close()  # the envs and the GAIL thread: none is left for the next test to count
    (w0, s0, r0, t0), (w1, s1, r1, t1) = states[False], states[True]
    assert len(w0) == len(w1) and all(torch.equal(a, b) for a, b in zip(w0, w1, strict=True))
    assert sorted(s0) == sorted(s1) and "Losses/GAIL Loss" in s0
    assert all(sorted(s0[k]) == sorted(s1[k]) for k in s0)
    assert r0 == r1 and torch.equal(t0, t1)


def test_a_finished_run_leaves_no_gail_thread_behind(tmp_path):
    """``learn.train`` releases the discriminator's thread when the run ends, so a process that
    trains many runs (the sweep's driver, demos_needed) does not collect idle threads."""
    import threading

    from mimicrete import learn
    from mimicrete.testing.toyenv import toy_config

    def gail_threads() -> int:
        return sum(t.name.startswith("gail") for t in threading.enumerate())

    before = gail_threads()
    for i in range(2):
        tr = learn.train(toy_config(tmp_path, gail=0.05, max_steps=1024), tmp_path / f"r{i}",
                         progress=False)  # fmt: skip
        assert tr.cfg.torch_settings.overlap_gail and tr.state.gail is not None
    assert gail_threads() == before
