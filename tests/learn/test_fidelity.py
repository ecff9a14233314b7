"""The paper-fidelity switches of issue 16, through the real CLI on the toy env: the sampled
evaluation (``eval --stochastic``), the stop on convergence, the BC warm start in passes and the
discriminator's input normalisation (ML-Agents' default: off)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from mimicrete import cli
from mimicrete.learn import config
from mimicrete.learn.gail import Gail
from mimicrete.learn.normalizer import FixedNorm
from mimicrete.testing.toyenv import toy_config


@pytest.fixture()
def toy_yaml(tmp_path: Path) -> Path:
    path = tmp_path / "toy.yaml"
    config.save(toy_config(tmp_path, max_steps=3072, buffer=512, ckpt=1024), path)
    return path


def train(cfg: Path, run_dir: Path, *extra: str) -> int:
    argv = ["train", "--config", str(cfg), "--run-dir", str(run_dir), "--no-progress",
            "--eval-episodes", "0", *extra]  # fmt: skip
    return cli.main(argv)


def test_stop_on_convergence_ends_the_run_and_records_the_step(toy_yaml, tmp_path, capsys):
    run_dir = tmp_path / "run"
    crit = "behavior.stop_on_convergence={installed_rate: 0.0, summaries: 2, min_episodes: 1}"
    assert train(toy_yaml, run_dir, "--set", crit) == 0
    rows = list(csv.DictReader(open(run_dir / "scalars.csv")))
    with_episodes = [float(r.get("Environment/Episodes") or 0) >= 1 for r in rows]
    # the run stopped at the second summary in a row with a finished episode, before 3072
    assert with_episodes[-2:] == [True, True]
    assert not (len(rows) >= 3 and with_episodes[-3])  # else it would have stopped a row earlier
    stop = int(rows[-1]["step"])
    assert stop < 3072
    conv = json.loads((run_dir / "run.json").read_text())["convergence"]
    assert conv == {
        "installed_rate": 0.0, "summaries": 2, "min_episodes": 1, "converged_at_step": stop
    }  # fmt: skip
    assert f"converged at step {stop}" in capsys.readouterr().out
    assert (run_dir / "checkpoints" / f"step_{stop:09d}.pt").exists()
    assert (run_dir / "policy.pt").exists() and (run_dir / "policy.onnx").exists()


def test_resuming_a_converged_run_keeps_it_as_it_was(toy_yaml, tmp_path):
    run_dir = tmp_path / "run"
    crit = "behavior.stop_on_convergence={installed_rate: 0.0, summaries: 2, min_episodes: 1}"
    assert train(toy_yaml, run_dir, "--set", crit) == 0
    info = json.loads((run_dir / "run.json").read_text())
    rows = (run_dir / "scalars.csv").read_text()
    cks = sorted(p.name for p in (run_dir / "checkpoints").iterdir())
    assert train(toy_yaml, run_dir, "--set", crit, "--resume") == 0
    assert json.loads((run_dir / "run.json").read_text()) == info  # converged_at_step kept
    assert (run_dir / "scalars.csv").read_text() == rows  # no update ran
    assert sorted(p.name for p in (run_dir / "checkpoints").iterdir()) == cks


def test_an_unmet_criterion_runs_to_max_steps(toy_yaml, tmp_path):
    run_dir = tmp_path / "run"
    assert train(toy_yaml, run_dir, "--stop-on-convergence",
                 "--set", "behavior.stop_on_convergence.min_episodes=100000") == 0  # fmt: skip
    conv = json.loads((run_dir / "run.json").read_text())["convergence"]
    assert conv["converged_at_step"] is None and conv["installed_rate"] == 0.99
    assert (run_dir / "checkpoints" / "step_000003072.pt").exists()


def test_bad_convergence_settings_name_the_field(toy_yaml, tmp_path, capsys):
    capsys.readouterr()
    crit = "behavior.stop_on_convergence={installed_rate: 1.5}"
    assert train(toy_yaml, tmp_path / "run", "--set", crit) == 2
    err = capsys.readouterr().err.strip()
    assert "stop_on_convergence.installed_rate: 1.5 is out of range" in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "run").exists()


def test_stochastic_eval_is_its_own_reproducible_file(toy_yaml, tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert train(toy_yaml, run_dir, "--max-steps", "1024") == 0
    assert cli.main(["eval", str(run_dir), "--episodes", "16"]) == 0
    det = json.loads((run_dir / "eval.json").read_text())
    assert cli.main(["eval", str(run_dir), "--episodes", "16", "--stochastic"]) == 0
    assert "eval_stochastic.json" in capsys.readouterr().out
    sto = json.loads((run_dir / "eval_stochastic.json").read_text())
    assert det["policy"] == "deterministic" and sto["policy"] == "stochastic"
    assert json.loads((run_dir / "eval.json").read_text()) == det  # left as it was
    assert sto["episodes"] == 16 and 0.0 <= sto["installed_rate"] <= sto["picked_rate"] <= 1.0
    assert cli.main(["eval", str(run_dir), "--episodes", "16", "--stochastic"]) == 0
    assert json.loads((run_dir / "eval_stochastic.json").read_text()) == sto  # same seed, same


def test_robust_eval_of_a_toy_run_is_a_usage_error(toy_yaml, tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert train(toy_yaml, run_dir, "--max-steps", "512") == 0
    capsys.readouterr()
    assert cli.main(["eval", str(run_dir), "--robust"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == ("mimicrete eval: error: starts 'robust' need the simulator's env, not Toy-v0")
    assert not (run_dir / "eval_robust.json").exists()


def test_warm_start_in_passes_is_recorded(toy_yaml, tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert train(toy_yaml, run_dir, "--max-steps", "512",
                 "--set", "behavior.behavioral_cloning.pretrain_passes=3") == 0  # fmt: skip
    warm = json.loads((run_dir / "run.json").read_text())["bc_warm_start"]
    per_pass = warm["demo_steps"] // 128  # the toy config's batch size
    assert warm["grad_steps"] == 3 * per_pass and warm["passes"] == pytest.approx(3.0)
    capsys.readouterr()
    both = ["--set", "behavior.behavioral_cloning.pretrain_steps=10",
            "--set", "behavior.behavioral_cloning.pretrain_passes=3"]  # fmt: skip
    assert train(toy_yaml, tmp_path / "run2", *both) == 2
    err = capsys.readouterr().err
    assert "behavioral_cloning.pretrain_passes" in err and "not both" in err


def test_discriminator_normalises_its_input_only_when_asked():
    x = np.random.default_rng(0).normal(3.0, 5.0, (64, 4)).astype(np.float32)
    raw = Gail(x, hidden=8, layers=1, lr=1e-3, normalize=False)
    norm = Gail(x, hidden=8, layers=1, lr=1e-3, normalize=True)
    assert isinstance(raw.disc.norm, torch.nn.Identity)
    assert isinstance(norm.disc.norm, FixedNorm)
    z = norm.disc.norm(torch.from_numpy(x))
    assert z.mean(0).abs().max() < 1e-5 and (z.std(0) - 1).abs().max() < 0.02
    cfg = config.from_dict({"behaviors": {"B": {"reward_signals": {"gail": {"demo_path": "d"}}}}})
    assert cfg.behavior.reward_signals.gail.network_settings.normalize is False  # ML-Agents
    for g in (2, 3, 4, 5, 6, 7, 8, 9):  # the group configs keep it on, as they were measured
        c = config.load(Path(__file__).parents[2] / "configs" / f"group{g}.yaml")
        assert c.behavior.reward_signals.gail.network_settings.normalize is True
