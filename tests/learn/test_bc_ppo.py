"""BC anneal schedule and learning, PPO schedules and loss pieces."""

import numpy as np
import pytest
import torch

from mimicrete.learn.bc import MIN_LR, BehavioralCloning, bc_learning_rate
from mimicrete.learn.evaluate import run_episodes
from mimicrete.learn.networks import Actor, ee_value_to_index
from mimicrete.learn.ppo import (
    PPOBatch,
    combine_advantages,
    explained_variance,
    linear_decay,
    ppo_loss,
    scheduled,
)
from mimicrete.testing import toyenv


def _toy_bc(*, demos, seed, hidden, steps, batch_size, num_epoch):
    """Toy expert demos, a 2-layer actor normalised on them, and BC at lr 1e-3 on it."""
    torch.manual_seed(0)
    d = toyenv.expert_demos(demos, seed=seed)
    actor = Actor(toyenv.OBS_DIM, 6, hidden, 2, normalize=True)
    actor.norm.update(torch.from_numpy(d["obs"]))
    bc = BehavioralCloning(
        actor,
        d["obs"],
        d["actions"],
        1e-3,
        steps=steps,
        batch_size=batch_size,
        num_epoch=num_epoch,
        samples_per_update=0,
    )
    return d, actor, bc


def test_bc_learning_rate_anneals_to_zero_over_its_steps():
    lr0 = 0.5 * 5e-4  # the paper: strength 0.5 x PPO's 5e-4
    assert bc_learning_rate(lr0, 100_000, 0) == pytest.approx(2.5e-4)
    assert bc_learning_rate(lr0, 100_000, 50_000) == pytest.approx(1.25e-4, rel=1e-6)
    assert bc_learning_rate(lr0, 100_000, 100_000) == pytest.approx(MIN_LR)
    assert bc_learning_rate(lr0, 100_000, 10**7) == pytest.approx(MIN_LR)
    assert bc_learning_rate(lr0, 0, 10**7) == lr0  # steps 0: constant (ML-Agents)


def test_bc_rounds_follow_ml_agents_order_of_the_learning_rate():
    """A round runs at the rate the previous one set (the first at the initial rate) and then
    sets the next from the current step: 100k steps at 10,240 per update give 10 rounds."""
    lr0 = 0.5 * 5e-4
    _, _, bc = _toy_bc(demos=4, seed=3, hidden=16, steps=100_000, batch_size=64, num_epoch=1)
    bc.initial_lr = bc.current_lr = lr0
    rng = np.random.default_rng(0)
    rates = []
    for u in range(1, 14):
        res = bc.update(u * 10_240, rng)
        if res is None:
            break
        rates.append(res[1])
    assert len(rates) == 10
    assert rates[0] == pytest.approx(lr0)
    assert rates[1] == pytest.approx(bc_learning_rate(lr0, 100_000, 10_240))
    assert rates[-1] == pytest.approx(bc_learning_rate(lr0, 100_000, 92_160))
    assert bc.current_lr == pytest.approx(MIN_LR)


def test_bc_stops_after_its_steps_and_learns_the_expert():
    d, actor, bc = _toy_bc(demos=30, seed=3, hidden=64, steps=1000, batch_size=128, num_epoch=3)
    rng = np.random.default_rng(0)
    assert bc.update(1000, rng) is not None  # the first round runs at the initial rate
    before = [p.clone() for p in actor.parameters()]
    assert bc.update(2000, rng) is None  # annealed out: no update
    assert all(torch.equal(a, b) for a, b in zip(before, actor.parameters(), strict=True))
    bc.steps = 0  # constant lr from here on
    bc.current_lr = bc.initial_lr
    first = bc.update(0, rng)[0]
    for _ in range(30):
        last = bc.update(0, rng)[0]
    assert last < 0.5 * first
    res = run_episodes(actor, "Toy-v0", 16, seed=11)
    assert res["installed_rate"] >= 0.9


def test_ee_command_mapping():
    v = torch.tensor([-1.0, -0.5, -0.2, 0.0, 0.49, 0.5, 1.0])
    assert ee_value_to_index(v).tolist() == [0, 0, 1, 1, 1, 2, 2]


def test_linear_schedules_like_ml_agents():
    assert linear_decay(5e-4, 1e-10, 0, 100) == 5e-4
    assert linear_decay(5e-4, 1e-10, 100, 100) == pytest.approx(1e-10)
    assert linear_decay(0.2, 0.1, 50, 100) == pytest.approx(0.15)
    assert linear_decay(0.01, 1e-5, 200, 100) == pytest.approx(1e-5)
    assert scheduled("constant", "linear", 0.2, 0.1, 50, 100) == 0.2
    assert scheduled(None, "linear", 0.2, 0.1, 50, 100) == pytest.approx(0.15)


def test_combine_advantages_is_mean_then_z_normalised():
    a = np.array([1.0, 2.0, 3.0, 6.0])
    b = np.array([3.0, 2.0, 1.0, 2.0])
    c = combine_advantages([a, b])
    m = (a + b) / 2
    np.testing.assert_allclose(c, (m - m.mean()) / m.std(), atol=1e-8)


def test_ppo_loss_ratio_one_and_clipping():
    torch.manual_seed(0)
    actor = Actor(5, 6, 16, 2, normalize=False)
    from mimicrete.learn.networks import Critic

    critic = Critic(5, 2, 16, 2, normalize=False)
    obs = torch.randn(32, 5)
    u, k, logp = actor.sample(obs)
    adv = torch.randn(32)
    with torch.no_grad():
        vals = critic(obs)
    b = PPOBatch(obs=obs, u=u, k=k, old_logp=logp, adv=adv, old_values=vals, returns=vals + 1.0)
    _, info = ppo_loss(actor, critic, b, 0.2, 0.01)
    pl, vl, ent = info.policy_loss, info.value_loss, info.entropy
    assert info.approx_kl == pytest.approx(0.0, abs=1e-6) and info.clipfrac == 0.0
    assert pl == pytest.approx(-adv.mean().item(), abs=1e-6)  # ratio 1 -> -mean(A)
    assert vl == pytest.approx(1.0, abs=1e-6)  # (returns - values)^2 = 1 per head
    # entropy (ML-Agents): mean over the 6 Gaussians of sigma 1/3 (0.5 ln(2 pi e) - ln 3 each)
    # + the 3-way categorical's
    h_gauss = 0.5 * np.log(2 * np.pi * np.e) - np.log(3)
    assert h_gauss < ent < h_gauss + np.log(3) + 1e-6
    # a big positive advantage with old logp far below: ratio clipped at 1 + eps
    lp_old = logp - 5.0
    b2 = PPOBatch(obs=obs, u=u, k=k, old_logp=lp_old, adv=torch.ones(32), old_values=vals,
                  returns=vals)  # fmt: skip
    _, info2 = ppo_loss(actor, critic, b2, 0.2, 0)
    assert info2.policy_loss == pytest.approx(-1.2, abs=1e-6)
    # CleanRL's diagnostics: every component's ratio is e^5, outside [0.8, 1.2]
    assert info2.clipfrac == 1.0
    assert info2.approx_kl == pytest.approx((np.exp(5.0) - 1.0) - 5.0, rel=1e-5)


def test_explained_variance():
    rng = np.random.default_rng(0)
    ret = rng.normal(size=1000)
    assert explained_variance(ret, ret) == 1.0
    assert explained_variance(np.zeros(1000), ret) == pytest.approx(0.0, abs=1e-12)
    noisy = ret + rng.normal(scale=0.5, size=1000)
    ev = explained_variance(noisy, ret)
    assert ev == pytest.approx(1.0 - np.var(noisy - ret) / np.var(ret))
    assert 0.6 < ev < 0.85  # about 1 - 0.25
    assert np.isnan(explained_variance(ret, np.ones(1000)))


def test_bc_pretrain_reduces_loss_at_constant_rate():
    _, _, bc = _toy_bc(demos=10, seed=4, hidden=32, steps=10, batch_size=64, num_epoch=1)
    losses = bc.pretrain(120, np.random.default_rng(0))
    assert len(losses) == 120
    assert np.mean(losses[-10:]) < 0.5 * np.mean(losses[:10])
    assert bc.opt.param_groups[0]["lr"] == 1e-3
