"""The forward half of the curriculum (demo_curriculum.forward_to: wide): once the demos are
solved, the env's own starts widen as episodes from them install, on the real vector env; the
scale survives a checkpoint; a bad forward_to is refused naming the field."""

import numpy as np
import pytest

from mimicrete import envs
from mimicrete.learn import config as config_mod
from mimicrete.learn.config import DemoCurriculumSettings
from mimicrete.learn.curriculum import DemoTrack, ReverseCurriculum


def _curriculum(num_envs: int, **kw) -> ReverseCurriculum:
    settings = DemoCurriculumSettings(forward_to="wide", forward_window=4, **kw)
    track = DemoTrack(seed=3, actions=np.zeros((20, 7), np.float32))
    c = ReverseCurriculum([track], settings, num_envs, np.random.default_rng(0))
    c.stage[0] = len(c.schedules[0])  # the demo is solved: the forward half may start
    return c


def _x_spread(env, n: int) -> tuple[float, float]:
    xs = [env.sim.start(i)["object_pose"][0] for i in range(n)]
    ys = [env.sim.start(i)["object_pose"][1] for i in range(n)]
    return max(xs) - min(xs), max(ys) - min(ys)


def test_the_starts_widen_as_episodes_from_them_install():
    n = 16
    env = envs.make_vec("TileSuction-v0", n, seed=0)
    obs, _ = env.reset(seed=0)
    c = _curriculum(n, forward_step=0.5, forward_threshold=0.75)
    everyone = np.ones(n, bool)
    c.restart(env, everyone, everyone, obs)
    assert c.forward_scale == 0.0
    # the paper's starts: y fixed at 0.32 m
    assert _x_spread(env, n)[1] == 0.0
    for i, ok in enumerate([True, True, False, True]):  # 3 of 4 install: >= 0.75
        c.record_own(i, ok)
    assert c.forward_scale == 0.5
    c.restart(env, everyone, np.zeros(n, bool), obs)  # every env restarts at the new scale
    dx, dy = _x_spread(env, n)
    assert dy > 0.01, "y now varies"
    # episodes begun at the old scale do not count; a window of failures does not widen
    c.env_scale[:2] = 0.0
    c.record_own(0, True)
    c.record_own(1, True)
    assert len(c.forward_results) == 0
    for i in range(4):
        c.record_own(4 + i, False)
    assert c.forward_scale == 0.5
    for i in range(4):
        c.record_own(8 + i, True)
    assert c.forward_scale == 1.0
    c.restart(env, everyone, np.zeros(n, bool), obs)
    for i in range(n):
        st = env.sim.start(i)
        assert abs(st["object_pose"][2]) <= np.radians(30) + 1e-6
    assert max(abs(env.sim.start(i)["object_pose"][2]) for i in range(n)) > 0.05, "turned"
    env.close()


def test_no_widening_while_a_demo_is_unsolved_and_the_scale_is_checkpointed():
    c = _curriculum(4, forward_step=0.1, forward_threshold=0.5)
    c.stage[0] = 0  # unsolved
    for i in range(4):
        c.record_own(i, True)
    assert c.forward_scale == 0.0
    c.stage[0] = len(c.schedules[0])
    for i in range(4):
        c.record_own(i, True)
    assert c.forward_scale == pytest.approx(0.1)
    d = _curriculum(4)
    d.load_state_dict(c.state_dict())
    assert d.forward_scale == pytest.approx(0.1) and d.summary()["Curriculum/Forward Scale"] == 0.1


def test_a_bad_forward_to_names_the_field(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text(
        "behaviors:\n  TileSuction:\n    behavioral_cloning: {demo_path: d, strength: 0.5}\n"
        "    demo_curriculum: {forward_to: everywhere}\n"
    )
    with pytest.raises(config_mod.ConfigError, match="demo_curriculum.forward_to"):
        config_mod.load(cfg)
