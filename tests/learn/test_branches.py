"""More than one command branch (ML-Agents' multi-branch discrete actions): Screw-v0's action is six
joint motions, the gripper command and the spin command, each command its own 3-way categorical.
Log-probabilities and entropy against a hand computation, BC's cross-entropy as ML-Agents'
``_behavioral_cloning_loss``, per-branch class weights, and a short run on the real Screw-v0 with
its checkpoint, resume, evaluation and ONNX policy."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from mimicrete.learn import bc as bc_mod
from mimicrete.learn.networks import Actor, env_action

from ._rollout import evaluated_first_episode, first_episode

LOGIT_BIAS = [0.0, 1.0, 2.0, -1.0, 0.5, 0.0]  # branch 0: (0, 1, 2); branch 1: (-1, 0.5, 0)
MU_BIAS = [0.1, -0.2, 0.3, 0.0, 0.5, -0.6]
LOG_STD = [-1.0, -0.5, 0.0, 0.2, -2.0, -1.1]


def _fixed_actor(n_branches: int = 2) -> Actor:
    """An actor whose outputs do not depend on the observation: mu = MU_BIAS, log sigma =
    LOG_STD, logits = LOGIT_BIAS (the first 3 * n_branches)."""
    a = Actor(4, 6, 8, 1, normalize=False, n_branches=n_branches)
    with torch.no_grad():
        a.mu.weight.zero_()
        a.mu.bias.copy_(torch.tensor(MU_BIAS))
        a.log_std.copy_(torch.tensor(LOG_STD))
        a.logits.weight.zero_()
        a.logits.bias.copy_(torch.tensor(LOGIT_BIAS[: 3 * n_branches]))
    return a


def _log_softmax(z: list[float]) -> list[float]:
    m = math.log(sum(math.exp(x) for x in z))
    return [x - m for x in z]


def test_two_branch_log_probs_and_entropy_by_hand():
    actor = _fixed_actor()
    assert actor.logits.out_features == 6
    obs = torch.randn(3, 4)
    u = torch.tensor([[0.0, 0.1, -0.4, 1.5, 0.45, -0.6]] * 3)
    k = torch.tensor([[2, 0], [1, 1], [0, 2]])
    logp, ent = actor.evaluate(obs, u, k)
    assert logp.shape == (3, 8) and ent.shape == (3,)
    lp0, lp1 = _log_softmax(LOGIT_BIAS[:3]), _log_softmax(LOGIT_BIAS[3:])
    for row in range(3):
        for j in range(6):  # each joint: the normal density's log at u
            s = math.exp(LOG_STD[j])
            z = (u[row, j].item() - MU_BIAS[j]) / s
            want = -0.5 * z * z - math.log(s) - 0.5 * math.log(2 * math.pi)
            assert logp[row, j].item() == pytest.approx(want, abs=1e-5)
        # one log-prob per branch: its chosen command's
        assert logp[row, 6].item() == pytest.approx(lp0[k[row, 0]], abs=1e-6)
        assert logp[row, 7].item() == pytest.approx(lp1[k[row, 1]], abs=1e-6)
    # entropy: the Gaussian's mean over the 6 dims + the two branches' entropies summed
    h_gauss = sum(0.5 + 0.5 * math.log(2 * math.pi) + ls for ls in LOG_STD) / 6
    h0 = -sum(math.exp(x) * x for x in lp0)
    h1 = -sum(math.exp(x) * x for x in lp1)
    assert ent.tolist() == pytest.approx([h_gauss + h0 + h1] * 3, abs=1e-5)
    # the same as torch.distributions' categoricals
    cats = [
        torch.distributions.Categorical(logits=torch.tensor(LOGIT_BIAS[i : i + 3])) for i in (0, 3)
    ]
    assert h0 + h1 == pytest.approx(sum(c.entropy().item() for c in cats), abs=1e-6)


def test_two_branch_sampling_and_deterministic_action():
    actor = _fixed_actor()
    torch.manual_seed(0)
    obs = torch.zeros(20_000, 4)
    u, k, logp = actor.sample(obs)
    assert u.shape == (20_000, 6) and k.shape == (20_000, 2) and logp.shape == (20_000, 8)
    for b, lo in ((0, 0), (1, 3)):  # each branch's frequencies are its own softmax
        freq = torch.bincount(k[:, b], minlength=3).double() / len(k)
        p = torch.softmax(torch.tensor(LOGIT_BIAS[lo : lo + 3], dtype=torch.float64), 0)
        assert torch.allclose(freq, p, atol=0.015), (b, freq, p)
    # the branches are drawn independently: the joint frequency is the product
    both = ((k[:, 0] == 2) & (k[:, 1] == 1)).double().mean().item()
    p0 = torch.softmax(torch.tensor(LOGIT_BIAS[:3]), 0)[2].item()
    p1 = torch.softmax(torch.tensor(LOGIT_BIAS[3:]), 0)[1].item()
    assert both == pytest.approx(p0 * p1, abs=0.015)
    act = env_action(u, k)
    assert act.shape == (20_000, 8)
    assert torch.equal(act[:, 6:], k.float() - 1.0)
    # deterministic: each branch's argmax (2 -> +1; 1 -> 0), the joints' clipped mean
    det = actor.deterministic(obs[:2])
    assert det[0].tolist() == pytest.approx([*MU_BIAS, 1.0, 0.0])


def test_one_branch_is_the_single_categorical_as_before():
    """One branch: the log-prob, entropy and BC loss of the one-categorical formulas (what the
    trainer computed before branches; the runs are bit-identical)."""
    torch.manual_seed(3)
    actor = Actor(5, 6, 16, 2, normalize=False)
    assert actor.n_branches == 1 and actor.logits.out_features == 3
    obs = torch.randn(64, 5)
    u, k, _ = actor.sample(obs)
    assert k.shape == (64, 1)
    logp, ent = actor.evaluate(obs, u, k)
    mu, log_std, logits = actor(obs)
    lp_d = torch.log_softmax(logits, -1).gather(-1, k)
    p = torch.softmax(logits, -1)
    ent_d = -(p * torch.log_softmax(logits, -1)).sum(-1)
    assert torch.equal(logp[:, 6:], lp_d)
    assert torch.equal(ent, (0.5 + 0.5 * math.log(2 * math.pi) + log_std).mean(-1) + ent_d)
    acts = torch.cat([torch.zeros(64, 6), (k.float() - 1.0)], -1)
    torch.manual_seed(9)
    got = bc_mod.bc_loss(actor, obs, acts)
    torch.manual_seed(9)
    sampled = mu + log_std.exp() * torch.randn_like(mu)
    want = sampled.pow(2).mean() + torch.nn.functional.cross_entropy(logits, k[:, 0])
    assert torch.equal(got, want)


def _ml_agents_bc_ce(logits: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
    """ML-Agents' ``_behavioral_cloning_loss`` discrete part: the mean over the stacked
    (branch, batch) one-hot cross-entropies."""
    per_branch = []
    for b in range(k.shape[1]):
        onehot = torch.nn.functional.one_hot(k[:, b], 3).float()
        lsm = torch.log_softmax(logits[:, 3 * b : 3 * b + 3], dim=1)
        per_branch.append(torch.sum(-lsm * onehot, dim=1))
    return torch.mean(torch.stack(per_branch))


def test_two_branch_bc_loss_is_mse_plus_mean_branch_cross_entropy():
    torch.manual_seed(0)
    actor = Actor(10, 6, 16, 2, normalize=False, n_branches=2)
    obs = torch.randn(32, 10)
    acts = torch.rand(32, 8) * 2 - 1
    acts[:, 6] = torch.tensor([-1.0, 0.0, 1.0, 1.0] * 8)
    acts[:, 7] = torch.tensor([0.0, 0.0, 0.0, 1.0, -1.0, 0.0, 1.0, 0.0] * 4)
    k = (acts[:, 6:] + 1).long()
    torch.manual_seed(1)
    got = bc_mod.bc_loss(actor, obs, acts)
    mu, log_std, logits = actor(obs)
    torch.manual_seed(1)
    mse = (mu + log_std.exp() * torch.randn_like(mu) - acts[:, :6]).pow(2).mean()
    assert got.item() == pytest.approx((mse + _ml_agents_bc_ce(logits, k)).item(), abs=1e-6)
    # weighted: each branch's own weights, by the command given in that branch
    w = torch.tensor([[2.0, 0.5, 3.0], [1.0, 4.0, 0.25]])
    torch.manual_seed(1)
    got_w = bc_mod.bc_loss(actor, obs, acts, w)
    ce = [
        torch.nn.functional.cross_entropy(logits[:, 3 * b : 3 * b + 3], k[:, b], reduction="none")
        * w[b, k[:, b]]
        for b in range(2)
    ]
    want = mse + torch.stack(ce).mean()
    assert got_w.item() == pytest.approx(want.item(), abs=1e-6)
    # the gradient reaches both branches' logits
    actor.zero_grad()
    got.backward()
    g = actor.logits.weight.grad
    assert g is not None and g[:3].abs().sum() > 0 and g[3:].abs().sum() > 0


def test_branch_class_weights_use_each_branch_own_frequencies():
    a = np.zeros((100, 8), np.float32)
    a[:50, 6] = 1.0  # gripper: closed half the time, open 10 %, fixed 40 %
    a[50:60, 6] = -1.0
    a[:4, 7] = 1.0  # spin: tighten 4 %, loosen 1 %, stop 95 %
    a[4, 7] = -1.0
    w = bc_mod.branch_class_weights(a, 6, 1.0)
    assert w is not None and w.shape == (2, 3)
    shares = np.array([[0.10, 0.40, 0.50], [0.01, 0.95, 0.04]])  # index order -1, 0, +1
    assert np.allclose(w.numpy() * shares, 1 / 3, atol=1e-6)  # balanced within each branch
    for b in range(2):
        assert torch.equal(w[b], bc_mod.ee_class_weights(a, 6 + b, 1.0))
    assert bc_mod.branch_class_weights(a, 6, 0.0) is None
    # one branch: the end-effector column's weights
    w1 = bc_mod.branch_class_weights(a[:, :7], 6, 1.0)
    assert w1 is not None and torch.equal(w1, bc_mod.ee_class_weights(a, 6, 1.0)[None])


# -- a short run on the real Screw-v0 --------------------------------------------------------------


@pytest.fixture(scope="module")
def screw_demos(tmp_path_factory):
    """Three converted screw demos (scripted hand logs through the teleoperation converter)."""
    from mimicrete import demonstrator as sy
    from mimicrete.teleop import convert as cv

    tmp = tmp_path_factory.mktemp("screw")
    for i, p in enumerate(sy.synth_hands("screw", 3, 500, tmp / "logs")):
        assert cv.convert_log(p, "screw", tmp / "demos", episode_index=i).installed
    return tmp / "demos"


def _screw_config():
    from mimicrete.learn import config

    from ._small import SMALL_RUN

    cfg = config.load(config.find_config_dir() / "fewdemo.yaml")
    return config.with_overrides(
        cfg,
        [
            *SMALL_RUN,
            "behavior.hyperparameters.buffer_size=512",
            "behavior.hyperparameters.batch_size=128",
            "behavior.summary_freq=512",
            "behavior.checkpoint_interval=512",
            "env_settings.env_id=Screw-v0",
            "env_settings.num_envs=8",
            "env_settings.seed=4",
        ],
    )


def test_short_two_branch_run_on_screw(tmp_path, screw_demos):
    import csv
    import json

    import onnxruntime as ort

    from mimicrete import demos, learn
    from mimicrete.learn import evaluate, run_files

    d = demos.load(screw_demos)
    assert d.actions.shape[1] == 8 and set(np.unique(d.actions[:, 7])) >= {0.0, 1.0}
    cfg = _screw_config()
    run = tmp_path / "run"
    tr = learn.train(cfg, run, demos=str(screw_demos), max_steps=1536, progress=False)
    assert tr.step == 1536 and tr.n_branches == 2 and tr.state.actor.logits.out_features == 6
    ro = tr.state.rollout
    assert ro.k.shape == (64, 8, 2) and ro.logp.shape == (64, 8, 8)
    assert set(np.unique(ro.env_actions[..., 7])) <= {-1.0, 0.0, 1.0}
    assert np.array_equal(ro.env_actions[..., 6:], ro.k - 1.0)
    assert (
        tr.state.bc is not None
        and tr.state.bc.ee_weight is not None
        and tr.state.bc.ee_weight.shape == (2, 3)
    )
    # the spin branch has its own weights: "tighten" is rarer than "stop" in the demos
    assert tr.state.bc.ee_weight[1, 2] > tr.state.bc.ee_weight[1, 1]
    rows = list(csv.DictReader((run / "scalars.csv").open()))
    assert len(rows) == 3
    # entropy: the Gaussian's (sigma ~ 1/3 or less after BC) + two 3-way branches, at most ln 3
    ent = float(rows[0]["Policy/Entropy"])
    assert math.isfinite(ent) and ent < 0.5 * math.log(2 * math.pi * math.e / 9) + 2 * math.log(3)
    assert all(math.isfinite(float(r["Losses/Policy Loss"])) for r in rows)
    # the checkpoints and policy.pt hold the two-branch actor; it loads as one
    assert len(list((run / "checkpoints").glob("step_*.pt"))) == 3
    actor, _ = run_files.load_policy(run)
    assert actor.n_branches == 2
    for key, v in tr.state.actor.state_dict().items():
        assert torch.equal(actor.state_dict()[key], v), key
    res = evaluate.evaluate_run(run, 4)
    assert res["episodes"] == 4 and res["env_id"] == "Screw-v0"
    # the length eval reports is the policy's: its first episode counted by stepping it by hand
    one = evaluated_first_episode(run, res["seed"])
    assert one["mean_episode_length"] == first_episode(run, res["seed"])[0]
    assert json.loads((run / "eval.json").read_text())["policy"] == "deterministic"
    sto = evaluate.evaluate_run(run, 4, stochastic=True)
    assert sto["episodes"] == 4
    # the ONNX policy: (B, 8) actions, the same as torch on the demos' observations
    import onnx

    model = onnx.load(str(run / "policy.onnx"))
    onnx.checker.check_model(model)
    (dim0, dim1) = model.graph.output[0].type.tensor_type.shape.dim
    assert dim0.dim_param and dim1.dim_value == 8
    sess = ort.InferenceSession(str(run / "policy.onnx"), providers=["CPUExecutionProvider"])
    obs = np.asarray(d.obs, np.float32)
    (out,) = sess.run(["actions"], {"obs": obs})
    with torch.no_grad():
        ref = actor.deterministic(torch.from_numpy(obs)).numpy()
    assert out.shape == (len(obs), 8)
    np.testing.assert_allclose(out[:, :6], ref[:, :6], atol=1e-5, rtol=0)
    np.testing.assert_array_equal(out[:, 6:], ref[:, 6:])
    assert set(np.unique(out[:, 6:])) <= {-1.0, 0.0, 1.0}
    one = np.concatenate([sess.run(["actions"], {"obs": obs[i : i + 1]})[0] for i in range(20)])
    np.testing.assert_allclose(one, out[:20], atol=1e-5, rtol=0)


def test_two_branch_resume_is_exact(tmp_path, screw_demos):
    """Interrupted after one update and resumed, the Screw run (PPO + BC, no curriculum: its
    per-env demo starts are not in a checkpoint, so a run with one does not resume exactly) ends
    with the weights of the uninterrupted one."""
    from mimicrete import learn
    from mimicrete.learn import config

    cfg = config.with_overrides(_screw_config(), ["behavior.demo_curriculum=null"])
    kw = {"demos": str(screw_demos), "max_steps": 1024, "progress": False}
    full = learn.train(cfg, tmp_path / "a", **kw)
    learn.train(cfg, tmp_path / "b", stop_after_updates=1, **kw)
    res = learn.train(cfg, tmp_path / "b", resume=True, **kw)
    assert res.step == full.step == 1024
    for key, v in full.state.actor.state_dict().items():
        assert torch.equal(res.state.actor.state_dict()[key], v), key
    for key, v in full.state.critic.state_dict().items():
        assert torch.equal(res.state.critic.state_dict()[key], v), key


def test_demos_of_another_task_are_refused(tmp_path, screw_demos):
    """Screw demos (8-dim actions) on TileSuction-v0 (7): a config error naming both."""
    from mimicrete import learn
    from mimicrete.learn import config

    cfg = config.with_overrides(_screw_config(), ["env_settings.env_id=TileSuction-v0"])
    with pytest.raises(config.ConfigError, match="8 dims.*takes 7"):
        learn.train(cfg, tmp_path / "run", demos=str(screw_demos), max_steps=512, progress=False)
