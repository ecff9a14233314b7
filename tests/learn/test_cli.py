"""End to end through the command line: a tiny train + eval run on the toy env (well under 60 s)."""

import argparse
import csv
import json

import pytest
import yaml

from mimicrete.cli import eval as cli_eval
from mimicrete.cli import train as cli_train
from mimicrete.learn import config, demo_data, plots
from mimicrete.testing.toyenv import toy_config

from ._rollout import evaluated_first_episode, first_episode


def _cli_main():
    from mimicrete import cli

    cli.build_parser()  # every subcommand's module imports
    return cli.main


def _write_cfg(tmp_path):
    cfg = toy_config(tmp_path, max_steps=3072, buffer=512, ckpt=1024)
    path = tmp_path / "toy.yaml"
    config.save(cfg, path)
    return path


def _train_args(cfg_path, run_dir, eval_episodes: int, *more: str) -> list[str]:
    """The flags of a quiet ``mimicrete train`` run of ``cfg_path`` into ``run_dir``."""
    return [
        "--config",
        str(cfg_path),
        "--run-dir",
        str(run_dir),
        "--no-progress",
        "--eval-episodes",
        str(eval_episodes),
        *more,
    ]


def _check_run(run_dir):
    resolved = yaml.safe_load((run_dir / "resolved_config.yaml").read_text())
    assert resolved["behaviors"]["Toy"]["max_steps"] == 3072
    with open(run_dir / "scalars.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [512 * i for i in range(1, 7)]
    for tag in (
        "Environment/Cumulative Reward",
        "Environment/Installed Rate",
        "Losses/Policy Loss",
        "Losses/Value Loss",
        "Losses/GAIL Loss",
        "Losses/Pretraining Loss",
        "Policy/Learning Rate",
        "Policy/Entropy",
        "Policy/GAIL Reward",
        "Environment/Picked Rate",
    ):
        assert tag in rows[0]
    lrs = [float(r["Policy/Learning Rate"]) for r in rows]
    assert all(a > b for a, b in zip(lrs, lrs[1:], strict=False))  # linear decay
    assert any((run_dir / "tensorboard").glob("events.out.tfevents.*"))
    assert len(list((run_dir / "checkpoints").glob("step_*.pt"))) == 3
    assert (run_dir / "policy.onnx").exists() and (run_dir / "policy.pt").exists()
    for png in ("extrinsic_reward.png", "picked_rate.png", "installed_rate.png"):
        assert (run_dir / "plots" / png).stat().st_size > 1000


def test_train_and_eval_through_cli(tmp_path, capsys):
    main = _cli_main()
    cfg_path = _write_cfg(tmp_path)
    run_dir = tmp_path / "run"
    assert main(["train", *_train_args(cfg_path, run_dir, 0)]) == 0
    _check_run(run_dir)
    capsys.readouterr()
    assert main(["eval", str(run_dir), "--episodes", "20"]) == 0
    out = capsys.readouterr().out
    assert "Picked rate" in out and "Installed rate" in out
    res = json.loads((run_dir / "eval.json").read_text())
    assert res["episodes"] == 20
    assert 0.0 <= res["installed_rate"] <= res["picked_rate"] <= 1.0
    # the mean length is of whole episodes, and an episode is what the policy does: one
    # evaluation episode is the one counted by stepping the policy by hand
    total = res["mean_episode_length"] * 20
    assert total == pytest.approx(round(total))
    one = evaluated_first_episode(run_dir, res["seed"])
    steps, ret, _ = first_episode(run_dir, res["seed"])
    assert one["mean_episode_length"] == steps
    assert one["mean_cumulative_reward"] == pytest.approx(ret, abs=1e-5)
    # --map draws the tile's starts: the toy env has none, which is said (exit 2), not drawn
    assert main(["eval", str(run_dir), "--episodes", "2", "--map"]) == 2
    assert "--map: Toy" in capsys.readouterr().err
    assert not list(run_dir.glob("*_map.png"))


def test_train_module_entry_points_and_resume_flag(tmp_path):
    cfg_path = _write_cfg(tmp_path)
    run_dir = tmp_path / "run"
    p = argparse.ArgumentParser()
    cli_train.configure(p)
    args = p.parse_args(_train_args(cfg_path, run_dir, 10, "--max-steps", "1024", "--seed", "3"))
    assert cli_train.main(args) == 0
    assert json.loads((run_dir / "eval.json").read_text())["episodes"] == 10
    assert config.load(run_dir / "resolved_config.yaml").env_settings.seed == 3
    # --resume with a larger budget continues from step 1024
    args = p.parse_args(
        _train_args(cfg_path, run_dir, 0, "--max-steps", "2048", "--seed", "3", "--resume")
    )
    assert cli_train.main(args) == 0
    steps = [int(r["step"]) for r in csv.DictReader(open(run_dir / "scalars.csv"))]
    assert steps == [512, 1024, 1536, 2048]
    e = argparse.ArgumentParser()
    cli_eval.configure(e)
    assert cli_eval.main(e.parse_args([str(run_dir), "--episodes", "4"])) == 0
    assert plots.compare([run_dir], tmp_path / "cmp.png").stat().st_size > 1000


def test_load_demos_selects_the_first_episodes(tmp_path):
    import collections

    import numpy as np

    from mimicrete.testing import toyenv

    d = toyenv.expert_demos(6, seed=2)
    np.savez(tmp_path / "d.npz", **d)
    sel = demo_data.load_demos(str(tmp_path / "d.npz"), 4)
    assert sorted(set(sel["episode"].tolist())) == [0, 1, 2, 3]
    assert len(sel["obs"]) == int(np.isin(d["episode"], [0, 1, 2, 3]).sum())
    with pytest.raises(ValueError, match="6 demo episodes"):
        demo_data.load_demos(str(tmp_path / "d.npz"), 60)
    with pytest.raises(FileNotFoundError):
        demo_data.load_demos(str(tmp_path / "missing"), 4)
    nt = collections.namedtuple("Demos", demo_data.DEMO_KEYS)(*[d[k] for k in demo_data.DEMO_KEYS])
    for form in (nt, tuple(nt), dict(nt._asdict())):
        out = demo_data.demo_arrays(form)
        assert all(np.array_equal(out[k], d[k]) for k in demo_data.DEMO_KEYS)
