"""configs/fewdemo.yaml's learner: the per-demo reverse curriculum (curriculum.py), replaying a
demo into one env of the VecEnv, class-weighted BC of the end-effector command, and a short
end-to-end run on TileSuction-v0 from hand-derived MCAP demos."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import torch

from mimicrete.learn import bc as bc_mod
from mimicrete.learn import config, curriculum
from mimicrete.learn.curriculum import DemoTrack, ReverseCurriculum, start_schedule
from mimicrete.learn.demo_data import read_demos
from mimicrete.learn.networks import Actor

from ._small import SMALL_RUN


@pytest.fixture(scope="module")
def hand_demos(tmp_path_factory) -> Path:
    """Three demos through the real teleoperation path (synth-hands + convert), seed 300."""
    from mimicrete.demonstrator import synth_hands
    from mimicrete.teleop import convert as cv

    root = tmp_path_factory.mktemp("fewdemo")
    logs = synth_hands("suction", 3, 300, root / "hands", progress=False)
    plan = cv.plan_outputs(logs, root / "demos", overwrite=True)
    for i, p in enumerate(logs):
        cv.convert_log(p, "suction", plan[p], episode_index=i)
    return root / "demos"


# -- the schedule and the curriculum's bookkeeping (no simulator) ---------------------------------


@pytest.mark.parametrize("length", [2, 3, 7, 10, 57, 310, 1000])
@pytest.mark.parametrize("frac", [0.01, 0.1, 0.2, 0.5, 0.99])
def test_start_schedule_walks_back_to_zero(length, frac):
    sc = start_schedule(length, frac)
    step = max(1, round(frac * length))
    assert sc[0] == max(0, length - step) and sc[-1] == 0
    assert all(a > b for a, b in zip(sc, sc[1:], strict=False))  # strictly backwards
    assert all(a - b <= step for a, b in zip(sc, sc[1:], strict=False))  # never more than a step
    assert all(0 <= s < length for s in sc)  # the last (install) action is never replayed


def _cur(lengths, **kw) -> ReverseCurriculum:
    s = config.DemoCurriculumSettings(**kw)
    tracks = [DemoTrack(i, np.zeros((n, 7), np.float32)) for i, n in enumerate(lengths)]
    return ReverseCurriculum(tracks, s, num_envs=4, rng=np.random.default_rng(0))


def test_start_moves_back_only_on_enough_installs():
    c = _cur([100], window=3, threshold=0.67, step_fraction=0.1)
    assert c.start(0) == 90
    for ok in (True, False, True):  # 2 of 3 >= 0.67? no: 0.667 < 0.67
        c.record(0, ok)
    assert c.start(0) == 90
    c.record(0, True)  # window now (False, True, True): still 0.667
    assert c.start(0) == 90
    c.record(0, True)  # (True, True, True)
    assert c.start(0) == 80 and len(c.results[0]) == 0  # the window restarts at the new start
    for _ in range(3 * 9):
        c.record(0, True)
    assert c.solved(0) and c.unsolved == [] and math.isclose(c.progress(), 1.0)
    c.record(0, False)  # a solved demo stays solved
    assert c.solved(0)


def test_episodes_from_passed_starts_do_not_move_the_start():
    c = _cur([100], window=3, threshold=0.67, step_fraction=0.1)
    for _ in range(3):
        c.record(0, True)
    assert c.start(0) == 80
    for _ in range(10):
        c.record(0, True, frontier=False)  # replays of start 90: logged, do not count
    assert c.start(0) == 80 and len(c.results[0]) == 0
    assert c.summary()["Curriculum/Installed Rate"] == 1.0


def test_choose_only_unsolved_demos_and_own_starts_at_reset_prob():
    c = _cur([50, 50, 50], reset_prob=0.75)
    c.stage[1] = len(c.schedules[1])  # demo 1 solved
    picks = np.array([c.choose() for _ in range(4000)])
    assert set(np.unique(picks)) == {-1, 0, 2}
    assert abs(np.mean(picks == -1) - 0.25) < 0.03
    assert abs(np.mean(picks == 0) - np.mean(picks == 2)) < 0.05
    c.stage = [len(sc) for sc in c.schedules]  # all solved: the env's own starts only
    assert {c.choose() for _ in range(100)} == {-1}
    assert {_cur([50], reset_prob=0.0).choose() for _ in range(100)} == {-1}


def test_pooled_demos_share_one_stage_and_window():
    """pooled: the frontier episodes of any demos fill one window; when it holds enough
    installs, every unsolved demo moves back one step of its own schedule."""
    c = _cur([100, 50, 100], window=3, threshold=0.67, step_fraction=0.2, pooled=True)
    assert [c.start(d) for d in range(3)] == [80, 40, 80]
    c.record(0, True)
    c.record(1, True)
    c.record(2, False, frontier=False)  # a passed start: logged, not judged
    assert c.stage == [0, 0, 0] and list(c.pool_results) == [True, True]
    c.record(2, True)
    assert c.stage == [1, 1, 1] and [c.start(d) for d in range(3)] == [60, 30, 60]
    assert all(len(r) == 0 for r in c.results)  # the per-demo windows stay unused
    d = _cur([100, 50, 100], window=3, threshold=0.67, step_fraction=0.2, pooled=True)
    c.record(1, True)
    d.load_state_dict(c.state_dict())
    assert d.stage == c.stage and list(d.pool_results) == [True]
    for _ in range(3 * 5):
        c.record(0, True)
    assert c.unsolved == [] and math.isclose(c.progress(), 1.0)
    assert "pool_results" not in _cur([10]).state_dict()  # unpooled checkpoints unchanged


def test_horizon_cut_only_for_demo_starts_that_did_not_end():
    c = _cur([40, 40])
    c.env_demo[:] = [-1, 0, 1, 0]
    c.env_steps[:] = [1000, 8, 9, 9]
    c.env_horizon[:] = [0, 10, 10, 10]
    ended = np.array([False, False, False, True])
    cut = c.over_horizon(ended)
    assert cut.tolist() == [False, False, True, False]  # own start never; env 3 ended itself
    assert c.env_steps.tolist() == [1001, 9, 10, 10]


def test_state_dict_round_trip():
    c = _cur([30, 60])
    for ok in (True, True, True, True, False):
        c.record(1, ok)
    c.replayed_steps = 123
    c.env_demo[:] = 1
    d = _cur([30, 60])
    d.load_state_dict(c.state_dict())
    assert d.stage == c.stage and [list(r) for r in d.results] == [list(r) for r in c.results]
    assert d.replayed_steps == 123 and (d.env_demo == 1).all()  # which demo each env is in
    old = {
        k: v for k, v in c.state_dict().items() if not k.startswith("env") and k != "episodes_done"
    }
    e = _cur([30, 60])
    e.env_demo[:] = 1
    e.load_state_dict(old)  # a checkpoint of an older version: envs restart from own starts
    assert (e.env_demo == -1).all()
    assert [d.choose() for _ in range(20)] == [c.choose() for _ in range(20)]


# -- class-weighted BC of the end-effector command ------------------------------------------------


def test_ee_class_weights_inverse_share_mean_one():
    a = np.zeros((100, 7), np.float32)
    a[:2, 6] = 1.0  # "on" twice
    a[2:7, 6] = -1.0  # "drop" 5 times, "fixed" 93 times
    w = bc_mod.ee_class_weights(a, 6, 1.0)
    assert w is not None
    share = np.array([0.05, 0.93, 0.02])  # index order drop, fixed, on
    assert np.allclose(w.numpy() * share, 1 / 3, atol=1e-6)  # balanced: equal total per class
    assert math.isclose(float((w.double().numpy() * share).sum()), 1.0, rel_tol=1e-6)
    w_half = bc_mod.ee_class_weights(a, 6, 0.5)
    assert w_half is not None and np.allclose(w_half[2] / w_half[1], math.sqrt(0.93 / 0.02))
    assert bc_mod.ee_class_weights(a, 6, 0.0) is None
    a[:, 6] = 0.0  # one command only: nothing to balance
    assert np.allclose(bc_mod.ee_class_weights(a, 6, 1.0).numpy(), 1.0)


def test_weighted_bc_loss_is_the_weighted_mean_of_cross_entropy():
    torch.manual_seed(0)
    actor = Actor(10, 6, 16, 2, normalize=False)
    obs = torch.randn(32, 10)
    acts = torch.zeros(32, 7)
    acts[:, 6] = torch.tensor([-1.0, 0.0, 1.0, 0.0] * 8)
    w = torch.tensor([2.0, 0.5, 3.0])
    torch.manual_seed(1)
    got = bc_mod.bc_loss(actor, obs, acts, w)
    torch.manual_seed(1)
    plain = bc_mod.bc_loss(actor, obs, acts)
    _, _, logits = actor(obs)
    k = (acts[:, 6] + 1).long()
    ce = torch.nn.functional.cross_entropy(logits, k, reduction="none")
    expect = plain - ce.mean() + (ce * w[k]).mean()
    assert torch.allclose(got, expect, atol=1e-6)


def test_weighted_bc_makes_the_rare_command_the_argmax_where_it_was_given():
    """1 "on" in 60 steps from nearly the same state as 59 "fixed" ones: unweighted BC keeps
    "fixed" the argmax there; balanced weights make "on" win in that neighbourhood."""
    rng = np.random.default_rng(0)
    obs = rng.normal(0, 1, (60, 4)).astype(np.float32)
    obs[:5] = obs[0] + rng.normal(0, 0.01, (5, 4)).astype(np.float32)  # 5 near-identical states
    acts = np.zeros((60, 7), np.float32)
    acts[0, 6] = 1.0  # ... only one labelled "on"
    winners = {}
    for balance in (0.0, 1.0):
        torch.manual_seed(0)
        actor = Actor(4, 6, 32, 2, normalize=False)
        b = bc_mod.BehavioralCloning(actor, obs, acts, 3e-3, 0, 60, 1, 0, ee_class_balance=balance)
        b.pretrain(400, np.random.default_rng(0))
        with torch.no_grad():
            winners[balance] = int(actor(torch.from_numpy(obs[:1]))[2].argmax())
    assert winners[0.0] == 1 and winners[1.0] == 2  # fixed vs on


# -- replaying demos in the simulator -------------------------------------------------------------


def test_replay_reaches_the_recorded_demo_states(hand_demos):
    """The curriculum's starts are the demonstrator's states: replaying a demo's first k actions
    from its seed gives back the observation it recorded at step k, and does not move the other
    envs."""
    from mimicrete import demos, envs

    d = demos.load(hand_demos)
    tracks = curriculum.demo_tracks(read_demos(hand_demos, None))
    assert [t.seed for t in tracks] == [int(m["seed"]) for m in d.metas]
    venv = envs.make_vec("TileSuction-v0", num_envs=3, seed=0)
    obs0, _ = venv.reset(seed=5)
    for j, (sl, tr) in enumerate(zip(d.episode_slices(), tracks, strict=True)):
        assert np.array_equal(tr.actions, d.actions[sl])
        for k in sorted({0, 1, tr.length // 2, tr.length - 1}):
            o = venv.reset_replay(2, tr.seed, tr.actions[:k])
            np.testing.assert_array_equal(o, d.obs[sl][k], err_msg=f"demo {j} step {k}")
    # env 0 was not moved by the replays into env 2: its next step is as a fresh copy's
    ref = envs.make_vec("TileSuction-v0", num_envs=3, seed=0)
    ref_obs, _ = ref.reset(seed=5)
    np.testing.assert_array_equal(ref_obs, obs0)
    a = np.zeros((3, 7), np.float32)
    np.testing.assert_array_equal(venv.step(a)[0][0], ref.step(a)[0][0])
    with pytest.raises(ValueError):
        venv.reset_replay(0, 1, np.zeros((3, 5), np.float32))  # wrong action size
    with pytest.raises(ValueError, match="ends at step 750"):
        venv.reset_replay(0, 1, np.zeros((750, 7), np.float32))  # truncated inside the replay
    with pytest.raises(ValueError, match="out of range"):
        venv.reset_replay(7, 1, np.zeros((1, 7), np.float32))  # no env 7


def test_fewdemo_config_loads_and_only_extends_the_schema():
    cfg = config.load(config.find_config_dir() / "fewdemo.yaml")
    b = cfg.behavior
    assert b.demo_curriculum is not None and b.reward_signals.gail is None
    assert b.behavioral_cloning is not None and b.behavioral_cloning.ee_class_balance == 1.0
    assert b.demo_episodes is None  # every demo of --demos DIR
    assert cfg.env_settings.env_id == "TileSuction-v0"
    for n in range(1, 10):  # the paper's groups do not use the extensions
        g = config.load(config.find_config_dir() / f"group{n}.yaml").behavior
        assert g.demo_curriculum is None
        assert g.behavioral_cloning is None or g.behavioral_cloning.ee_class_balance == 0.0
    with pytest.raises(config.ConfigError, match="threshold"):
        config.with_overrides(cfg, ["behavior.demo_curriculum.threshold=1.5"])
    with pytest.raises(config.ConfigError, match="unknown"):
        config.with_overrides(cfg, ["behavior.demo_curriculum.bogus=1"])
    with pytest.raises(config.ConfigError, match="max_demos"):
        config.with_overrides(cfg, ["behavior.demo_curriculum.max_demos=0"])


def _small_fewdemo(max_steps: int, *overrides: str) -> config.TrainerConfig:
    """configs/fewdemo.yaml shrunk to a short run on 8 envs, summaries every 1024 steps."""
    return config.with_overrides(
        config.load(config.find_config_dir() / "fewdemo.yaml"),
        [
            *SMALL_RUN,
            f"behavior.max_steps={max_steps}",
            "behavior.summary_freq=1024",
            "env_settings.num_envs=8",
            *overrides,
        ],
    )


def test_short_fewdemo_run(hand_demos, tmp_path):
    """configs/fewdemo.yaml, shrunk: episodes start inside the demos, are cut at their horizon,
    are counted apart from the env's own starts, and the run resumes exactly."""
    from mimicrete import learn
    from mimicrete.learn import run_files

    cfg = _small_fewdemo(
        3072,
        "behavior.checkpoint_interval=2048",
        "behavior.demo_curriculum.min_horizon=5",
        "behavior.demo_curriculum.horizon_ratio=0.1",
        # judged on 50 episodes: no demo is solved in 3072 steps, so demo starts go on to the end
        "behavior.demo_curriculum.window=50",
    )
    run = tmp_path / "run"
    tr = learn.train(cfg, run, demos=str(hand_demos), progress=False)
    cur = tr.state.curriculum
    assert cur is not None and len(cur.tracks) == 3 and tr.step == 3072
    assert cur.replayed_steps > 0
    sc = run_files.read_scalars(run)
    assert sc["Curriculum/Episodes"][1].sum() > 10  # short horizons: many demo-start episodes
    prog = sc["Curriculum/Progress"][1]
    assert len(prog) == 3 and ((prog >= 0) & (prog <= 1)).all()
    assert (np.diff(sc["Environment/Elapsed Seconds"][1]) > 0).all()
    # a run stopped at its checkpoint and resumed is the uninterrupted run, bit for bit: the
    # curriculum's per-env demo starts are in the checkpoint beside the envs' own state
    run2 = tmp_path / "run2"
    b1 = learn.train(cfg, run2, demos=str(hand_demos), progress=False, stop_after_updates=2)
    assert b1.state.curriculum is not None and b1.step == 2048
    ck = run_files.load_checkpoint(run_files.latest_checkpoint(run2))
    assert ck["curriculum"]["stage"] == b1.state.curriculum.stage
    assert (ck["curriculum"]["env_demo"] >= 0).any()  # some envs were inside a demo
    b2 = learn.train(cfg, run2, demos=str(hand_demos), progress=False, resume=True)
    assert b2.step == tr.step == 3072
    for k, v in tr.state.actor.state_dict().items():
        assert torch.equal(v, b2.state.actor.state_dict()[k]), k
    a, b = tr.state.curriculum.state_dict(), b2.state.curriculum.state_dict()
    assert a["stage"] == b["stage"] and a["results"] == b["results"]
    assert a["replayed_steps"] == b["replayed_steps"] and a["rng"] == b["rng"]
    np.testing.assert_array_equal(a["env_demo"], b["env_demo"])
    wall = {"Environment/Elapsed Seconds", "Environment/Steps Per Second"}
    s1, s2 = run_files.read_scalars(run), run_files.read_scalars(run2)
    assert {k for k in s1 if k not in wall} == {k for k in s2 if k not in wall}
    for k in s1:
        if k not in wall:
            np.testing.assert_array_equal(s1[k][1], s2[k][1], err_msg=k)
    tr2 = learn.train(cfg, run2, demos=str(hand_demos), progress=False, resume=True)
    assert tr2.step == 3072
    assert all(
        a >= b for a, b in zip(tr2.state.curriculum.stage, b1.state.curriculum.stage, strict=True)
    )


def test_max_demos_walks_back_the_first_demos_only(hand_demos, tmp_path):
    """``demo_curriculum.max_demos`` caps the demos the curriculum starts from (the first ones, in
    the trainer's order); BC still reads every demo."""
    from mimicrete import learn

    cfg = _small_fewdemo(
        1024, "behavior.checkpoint_interval=1024", "behavior.demo_curriculum.max_demos=2"
    )
    tr = learn.train(cfg, tmp_path / "run", demos=str(hand_demos), progress=False)
    assert tr.state.curriculum is not None
    every = curriculum.demo_tracks(read_demos(hand_demos, None))
    assert [t.seed for t in tr.state.curriculum.tracks] == [t.seed for t in every[:2]]
    assert len(every) == 3 and len({t.seed for t in every}) == 3
    assert set(tr.state.curriculum.env_demo.tolist()) <= {-1, 0, 1}
    assert tr.demo_steps_loaded == sum(t.length for t in every)  # BC read all three


def test_the_curriculum_starts_from_the_demos_bc_reads(hand_demos, tmp_path):
    """The demos are read once, for BC and the curriculum alike: with ``--skip-bad-demos`` a
    damaged file in the directory is left out of both (the curriculum used to read the
    directory again by itself, and stopped at the damaged file)."""
    import json
    import shutil

    from mimicrete import learn

    demos = tmp_path / "demos"
    shutil.copytree(hand_demos, demos)
    (demos / "zz_cut.mcap").write_bytes(b"\x89MCAP0\r\n cut short")
    cfg = _small_fewdemo(1024, "behavior.checkpoint_interval=1024")
    run = tmp_path / "run"
    tr = learn.train(cfg, run, demos=str(demos), progress=False, skip_bad_demos=True)
    assert tr.state.curriculum is not None and len(tr.state.curriculum.tracks) == 3
    assert tr.demos is not None
    assert [t.seed for t in tr.state.curriculum.tracks] == [
        int(m["seed"]) for m in tr.demos.loaded.metas
    ]
    info = json.loads((run / "run.json").read_text())
    assert len(info["demo_files_skipped"]) == 1 and "zz_cut.mcap" in info["demo_files_skipped"][0]
