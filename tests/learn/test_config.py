"""The nine group configs are exactly the paper's Tables 3 and 4 (ML-Agents shape)."""

from pathlib import Path

import pytest
import yaml

from mimicrete.learn import config

CONFIGS = Path(__file__).resolve().parents[2] / "configs"

# Table 3: (extrinsic strength, gail strength, bc strength, demonstrations); None = not used.
TABLE3 = {
    1: (1.0, None, None, None),
    2: (None, 1.0, None, 60),
    3: (1.0, 0.005, 0.5, 60),
    4: (1.0, 0.01, 0.5, 60),
    5: (1.0, 0.1, 0.5, 60),
    6: (0.5, 0.5, 0.5, 60),
    7: (0.1, 1.0, 0.5, 60),
    8: (1.0, 0.01, 0.5, 20),
    9: (1.0, 0.01, 0.5, 10),
}


@pytest.mark.parametrize("group", range(1, 10))
def test_group_matches_tables_3_and_4(group):
    cfg = config.load(CONFIGS / f"group{group}.yaml")
    b = cfg.behavior
    h = b.hyperparameters
    # Table 4, PPO column
    assert (h.batch_size, h.buffer_size, h.learning_rate) == (512, 10240, 0.0005)
    assert (h.epsilon, h.lambd, h.beta) == (0.2, 0.95, 0.01)
    assert b.time_horizon == 400 and b.max_steps == 5_000_000
    assert (b.network_settings.hidden_units, b.network_settings.num_layers) == (256, 3)
    assert b.trainer_type == "ppo"
    ext, gail, bc, demos = TABLE3[group]
    rs = b.reward_signals
    assert (rs.extrinsic.strength if rs.extrinsic else None) == ext
    assert (rs.gail.strength if rs.gail else None) == gail
    assert (b.behavioral_cloning.strength if b.behavioral_cloning else None) == bc
    assert b.demo_episodes == demos
    if rs.gail is not None:  # Table 4, GAIL column
        assert rs.gail.gamma == 0.99 and rs.gail.learning_rate == 0.0005
        assert (rs.gail.network_settings.hidden_units, rs.gail.network_settings.num_layers) == (
            256,
            3,
        )
        assert rs.gail.use_actions is False
    if b.behavioral_cloning is not None:  # Table 4, BC column
        assert b.behavioral_cloning.steps == 100_000
        assert b.behavioral_cloning.pretrain_steps == 2000  # extension (paper §4: BC pre-trains)
    # extension: the demonstrator's pauses are left out wherever demos are read
    assert b.demo_drop_idle == (0.1 if demos else 0.0)
    assert h.buffer_size % cfg.env_settings.num_envs == 0


def test_round_trip_and_overrides(tmp_path):
    cfg = config.load(CONFIGS / "group4.yaml")
    config.save(cfg, tmp_path / "c.yaml")
    again = config.load(tmp_path / "c.yaml")
    assert again == cfg
    o = config.with_overrides(
        cfg,
        [
            "behavior.reward_signals.gail.survivor_bias=none",
            "env_settings.seed=7",
            "behavior.max_steps=1000",
        ],
    )
    assert o.behavior.reward_signals.gail.survivor_bias == "none"
    assert o.env_settings.seed == 7 and o.behavior.max_steps == 1000
    assert cfg.behavior.max_steps == 5_000_000  # original untouched


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d["behaviors"]["TileSuction"]["hyperparameters"].update(batchsize=3), "unknown"),
        (lambda d: d["behaviors"]["TileSuction"].update(trainer_type="sac"), "ppo"),
        (
            lambda d: d["behaviors"]["TileSuction"]["hyperparameters"].update(batch_size="x"),
            "integer",
        ),
        (lambda d: d["env_settings"].update(num_envs=7), "divide"),
        (
            lambda d: d["behaviors"]["TileSuction"]["reward_signals"]["gail"].update(
                survivor_bias="maybe"
            ),
            "survivor_bias",
        ),
        (
            lambda d: d["behaviors"]["TileSuction"]["behavioral_cloning"].update(
                generate_speed=0.5
            ),
            r"behavioral_cloning.generate_speed.*0.5",
        ),
    ],
)
def test_bad_configs_are_rejected(mutate, message):
    data = yaml.safe_load((CONFIGS / "group3.yaml").read_text())
    mutate(data)
    with pytest.raises(config.ConfigError, match=message):
        config.from_dict(data)


def test_demo_drop_idle_range():
    cfg = config.load(CONFIGS / "group4.yaml")
    assert config.with_overrides(cfg, ["behavior.demo_drop_idle=0"]).behavior.demo_drop_idle == 0
    for bad in ("-0.1", "1.0"):
        with pytest.raises(config.ConfigError, match="demo_drop_idle"):
            config.with_overrides(cfg, [f"behavior.demo_drop_idle={bad}"])


def test_init_std_sets_the_policys_initial_sigma_and_is_range_checked(tmp_path):
    """``behavior.init_std`` (extension): the actor's initial sigma; the default is ML-Agents'
    effective 1/3 (bit for bit the old initialisation); out of (0, 1] names the field."""
    import math

    import torch

    from mimicrete.learn.networks import Actor
    from mimicrete.learn.trainer import Trainer
    from mimicrete.testing.toyenv import toy_config

    base = toy_config(tmp_path)
    assert base.behavior.init_std == 1.0 / 3.0
    assert torch.equal(Actor(4, 6, 8, 1, False).log_std.data, torch.full((6,), -math.log(3.0)))
    cfg = config.with_overrides(base, ["behavior.init_std=0.05"])
    tr = Trainer(cfg, tmp_path / "run", None, 10_000)
    assert torch.allclose(tr.state.actor.log_std.exp(), torch.full((6,), 0.05))
    tr.state.env.close()
    with pytest.raises(config.ConfigError, match=r"init_std: 0.0 is"):
        config.with_overrides(base, ["behavior.init_std=0.0"])
