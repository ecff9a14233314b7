"""`mimicrete train` / `mimicrete eval` under bad input, through the real CLI (issue 15): every user
error is one line ``mimicrete <cmd>: error: ...`` naming the field or file, exit 2; a failure
(a non-finite loss) exit 1; nothing lost (the last good checkpoint stays, an old run is not
mixed into a new one, the CSV holds each step once)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import torch

from mimicrete import cli
from mimicrete.learn import config
from mimicrete.learn.run_files import TAGS, WALL_CLOCK_TAGS
from mimicrete.testing.toyenv import toy_config


@pytest.fixture()
def toy_yaml(tmp_path: Path) -> Path:
    path = tmp_path / "toy.yaml"
    config.save(toy_config(tmp_path, max_steps=3072, buffer=512, ckpt=1024), path)
    return path


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    capsys.readouterr()
    rc = cli.main(argv)
    out, err = capsys.readouterr()
    return rc, out, err


def one_error_line(err: str, cmd: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"mimicrete {cmd}: error: "), lines[0]
    assert "Traceback" not in err
    return lines[0]


def train_argv(cfg: Path, run_dir: Path, *extra: str) -> list[str]:
    return ["train", "--config", str(cfg), "--run-dir", str(run_dir), "--no-progress",
            "--eval-episodes", "0", *extra]  # fmt: skip


@pytest.mark.parametrize(
    ("override", "field"),
    [
        ("behavior.reward_signals.extrinsic.gamma=7", "extrinsic.gamma: 7.0 is out of range"),
        ("behavior.hyperparameters.epsilon=-0.2", "hyperparameters.epsilon: -0.2 is out of range"),
        ("behavior.hyperparameters.num_epoch=0", "hyperparameters.num_epoch: 0 is out of range"),
        ("behavior.time_horizon=0", "time_horizon: 0 is out of range"),
        ("behavior.checkpoint_interval=-1", "checkpoint_interval: -1 is out of range"),
        ("torch_settings.num_threads=-4", "torch_settings.num_threads: -4 is out of range"),
        ("behavior.demo_episodes=-1", "demo_episodes: -1 is out of range"),
        ("behavior.reward_signals.gail.strength=.nan", "gail.strength: nan is out of range"),
        ("behavior.reward_signals.gail.gamma=.inf", "gail.gamma: inf is out of range"),
        ("behavior.hyperparameters.learning_rate=0", "learning_rate: 0.0 is out of range"),
        ("behavior.hyperparameters.lambd=1.5", "hyperparameters.lambd: 1.5 is out of range"),
        ("behavior.keep_checkpoints=0", "keep_checkpoints: 0 is out of range"),
        ("behavior.summary_freq=0", "summary_freq: 0 is out of range"),
        ("behavior.max_steps=0", "max_steps: 0 is out of range"),
        ("behavior.network_settings.hidden_units=0", "hidden_units: 0 is out of range"),
        ("behavior.behavioral_cloning.steps=-5", "behavioral_cloning.steps: -5 is out of range"),
        ("env_settings.seed=-1", "env_settings.seed: -1 is out of range"),
        ("env_settings.seed=4294967296", "env_settings.seed: 4294967296 is out of range"),
        ("env_settings.num_envs=0", "env_settings.num_envs: 0 is out of range"),
        ("torch_settings.device=cuda", "torch_settings.device: 'cuda' is not supported"),
    ],
)
def test_config_fields_are_range_checked_with_the_field_named(
    override, field, toy_yaml, tmp_path, capsys
):
    rc, out, err = run(train_argv(toy_yaml, tmp_path / "run", "--set", override), capsys)
    assert rc == 2
    line = one_error_line(err, "train")
    assert field in line and str(toy_yaml) in line
    assert not (tmp_path / "run" / "scalars.csv").exists()


def test_bad_values_in_the_config_file_itself(toy_yaml, tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text(toy_yaml.read_text().replace("gamma: 0.99", "gamma: 7", 1))
    rc, _, err = run(train_argv(bad, tmp_path / "run"), capsys)
    assert rc == 2 and "gamma: 7.0 is out of range (allowed: [0, 1])" in one_error_line(
        err, "train"
    )
    bad.write_text("behaviors: [unclosed\n")
    rc, _, err = run(train_argv(bad, tmp_path / "run"), capsys)
    assert rc == 2 and "not valid YAML" in one_error_line(err, "train")
    rc, _, err = run(train_argv(tmp_path / "missing.yaml", tmp_path / "run"), capsys)
    assert rc == 2 and "missing.yaml does not exist" in one_error_line(err, "train")


def test_a_number_written_without_a_dot_is_a_number(toy_yaml):
    cfg = config.with_overrides(config.load(toy_yaml), ["behavior.hyperparameters.beta=1e-3"])
    assert cfg.behavior.hyperparameters.beta == 1e-3  # YAML 1.1 reads 1e-3 as a string


def test_non_finite_loss_stops_and_keeps_the_last_good_checkpoint(toy_yaml, tmp_path, capsys):
    rd = tmp_path / "run"
    assert run(train_argv(toy_yaml, rd, "--max-steps", "2048"), capsys)[0] == 0
    # value weights that overflow in the first update after the resume (a resume may not change
    # the learning rate: that would shape the run)
    last = rd / "checkpoints" / "step_000002048.pt"
    s = torch.load(last, weights_only=False)
    s["critic"] = {k: v * 1e30 if k.endswith("weight") else v for k, v in s["critic"].items()}
    torch.save(s, last)
    before = {p.name: p.read_bytes() for p in (rd / "checkpoints").iterdir()}
    rows_before = (rd / "scalars.csv").read_text()
    argv = train_argv(toy_yaml, rd, "--resume", "--max-steps", "3072")
    rc, _, err = run(argv, capsys)
    assert rc == 1
    line = one_error_line(err, "train")
    assert "loss is nan" in line or "loss is inf" in line
    assert "step_000002048.pt" in line  # names the checkpoint that is kept
    after = {p.name: p.read_bytes() for p in (rd / "checkpoints").iterdir()}
    assert after == before  # nothing written from the broken update
    assert (rd / "scalars.csv").read_text() == rows_before
    s = torch.load(rd / "checkpoints" / "step_000002048.pt", weights_only=False)
    assert all(torch.isfinite(v).all() for v in s["actor"].values())


def test_a_run_dir_holding_another_run_is_refused_without_resume_or_force(
    toy_yaml, tmp_path, capsys
):
    rd = tmp_path / "run"
    assert run(train_argv(toy_yaml, rd), capsys)[0] == 0  # 3072 steps: checkpoints 1024-3072
    assert len(list((rd / "checkpoints").glob("*.pt"))) == 3
    rc, _, err = run(train_argv(toy_yaml, rd, "--max-steps", "1024"), capsys)
    assert rc == 2
    assert "holds another run" in one_error_line(err, "train")
    assert len(list((rd / "checkpoints").glob("*.pt"))) == 3  # untouched
    # --force replaces it: none of the old run's (higher-step) checkpoints survive
    rc, _, _ = run(train_argv(toy_yaml, rd, "--max-steps", "1024", "--force"), capsys)
    assert rc == 0
    assert sorted(p.name for p in (rd / "checkpoints").glob("*.pt")) == ["step_000001024.pt"]
    assert torch.load(rd / "policy.pt", weights_only=False)["step"] == 1024
    with open(rd / "scalars.csv") as f:
        assert [int(r["step"]) for r in csv.DictReader(f)] == [512, 1024]
    # --resume with nothing to resume, and --resume with --force, are user errors
    rc, _, err = run(train_argv(toy_yaml, tmp_path / "empty", "--resume"), capsys)
    assert rc == 2 and "no checkpoint" in one_error_line(err, "train")
    with pytest.raises(SystemExit) as e:
        cli.main(train_argv(toy_yaml, rd, "--resume", "--force"))
    assert e.value.code == 2


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with open(path) as f:
        return list(csv.DictReader(f))


def test_csv_has_each_step_once_after_an_interrupted_run_is_resumed(toy_yaml, tmp_path, capsys):
    """The interrupted run logged 1536 after its last checkpoint (1024), like a run killed there;
    the resumed run logs 1536 again: the CSV keeps one row per step, equal to the uninterrupted
    run's (wall-clock column aside)."""
    from mimicrete import learn

    cfg = config.load(toy_yaml)
    learn.train(cfg, tmp_path / "a", progress=False)
    learn.train(cfg, tmp_path / "b", progress=False, stop_after_updates=3)
    assert [int(r["step"]) for r in _csv_rows(tmp_path / "b/scalars.csv")] == [512, 1024, 1536]
    rc, _, _ = run(train_argv(toy_yaml, tmp_path / "b", "--resume"), capsys)
    assert rc == 0
    ra, rb = _csv_rows(tmp_path / "a/scalars.csv"), _csv_rows(tmp_path / "b/scalars.csv")
    assert [int(r["step"]) for r in rb] == [512 * i for i in range(1, 7)]
    assert list(rb[0]) == ["step", *TAGS]
    for x, y in zip(ra, rb, strict=True):
        for timing in WALL_CLOCK_TAGS:
            x.pop(timing)
            y.pop(timing)
        assert x == y


def test_eval_bad_input_is_one_line(toy_yaml, tmp_path, capsys):
    rc, _, err = run(["eval", str(tmp_path / "nowhere")], capsys)
    assert rc == 2 and "nowhere: no such run directory" in one_error_line(err, "eval")
    rd = tmp_path / "run"
    assert run(train_argv(toy_yaml, rd, "--max-steps", "512"), capsys)[0] == 0
    rc, _, err = run(["eval", str(rd), "--episodes", "0"], capsys)
    assert rc == 2 and "--episodes: at least 1, got 0" in one_error_line(err, "eval")
    good = (rd / "policy.pt").read_bytes()
    for bad in (good[:500], b"garbage\n", b""):
        (rd / "policy.pt").write_bytes(bad)
        rc, _, err = run(["eval", str(rd), "--episodes", "2"], capsys)
        assert rc == 2
        assert f"{rd / 'policy.pt'}: not a readable policy" in one_error_line(err, "eval")
    (rd / "policy.pt").unlink()
    rc, _, err = run(["eval", str(rd), "--episodes", "2"], capsys)
    assert rc == 2 and "policy.pt does not exist" in one_error_line(err, "eval")
    # a policy of another observation size (trained before the task's frame changed)
    (rd / "policy.pt").write_bytes(good)
    pol = torch.load(rd / "policy.pt", weights_only=False)
    n = int(pol["obs_dim"])
    a = pol["actor"]
    for k in ("norm.mean", "norm.var"):
        a[k] = torch.cat([a[k], a[k][:6]])
    a["body.0.weight"] = torch.cat([a["body.0.weight"], a["body.0.weight"][:, :6]], 1)
    pol["obs_dim"] = n + 6
    torch.save(pol, rd / "policy.pt")
    rc, _, err = run(["eval", str(rd), "--episodes", "2"], capsys)
    line = one_error_line(err, "eval")
    assert rc == 2 and f"{rd / 'policy.pt'}: the policy reads {n + 6}-float observations" in line
    assert f"gives {n} (trained with an older observation layout" in line
    (rd / "policy.pt").write_bytes(good)
    rc, out, _ = run(["eval", str(rd), "--episodes", "2"], capsys)
    assert rc == 0 and json.loads((rd / "eval.json").read_text())["episodes"] == 2


# ----------------------------------------------------------------------------------------------
# bad demo files (real MCAP demos on the real env)
# ----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory) -> Path:
    """Two MCAP demos made the way `make demos` makes them (synth-hands + convert)."""
    root = tmp_path_factory.mktemp("demos")
    argv = ["synth-hands", "--task", "suction", "--episodes", "2", "--seed", "0", "--out"]
    assert cli.main([*argv, str(root / "hands")]) == 0
    argv = ["convert", str(root / "hands"), "--task", "suction", "--no-progress", "--out"]
    assert cli.main([*argv, str(root / "demos")]) == 0
    assert len(list((root / "demos").glob("*.mcap"))) == 2
    return root / "demos"


def _real_argv(run_dir: Path, demos: Path, *extra: str) -> list[str]:
    cfg = config.find_config_dir() / "group4.yaml"
    sets = [
        "behavior.hyperparameters.buffer_size=512",
        "behavior.hyperparameters.batch_size=256",
        "behavior.network_settings.hidden_units=32",
        "behavior.reward_signals.gail.network_settings.hidden_units=32",
        "behavior.behavioral_cloning.pretrain_steps=5",
        "behavior.demo_episodes=2",
    ]
    return [
        *train_argv(cfg, run_dir, "--max-steps", "512", "--num-envs", "8", *extra),
        "--demos",
        str(demos),
        *[a for s in sets for a in ("--set", s)],
    ]


@pytest.mark.parametrize("damage", ["cut", "empty", "not-mcap"])
def test_a_bad_demo_file_is_named_and_skip_bad_demos_goes_on(damage, demo_dir, tmp_path, capsys):
    mixed = tmp_path / "demos"
    mixed.mkdir()
    for i, f in enumerate(sorted(demo_dir.glob("*.mcap"))):
        (mixed / f"take_{i}.mcap").write_bytes(f.read_bytes())
    good = (mixed / "take_0.mcap").read_bytes()
    bad = mixed / "take_2.mcap"
    bad.write_bytes({"cut": good[: len(good) // 2], "empty": b"", "not-mcap": b"hello\n"}[damage])
    # the bad file alone, then in a directory: one line naming it, nothing written
    for target in (bad, mixed):
        rd = tmp_path / f"run-{target.name}"
        rc, _, err = run(_real_argv(rd, target), capsys)
        assert rc == 2
        line = one_error_line(err, "train")
        assert str(bad) in line
        assert not any(rd.iterdir()) if rd.exists() else True
    # --skip-bad-demos trains on the two good files and records the bad one in run.json
    rd = tmp_path / "run-skip"
    rc, out, _ = run(_real_argv(rd, mixed, "--skip-bad-demos"), capsys)
    assert rc == 0 and f"skipped demo: {bad}" in out
    info = json.loads((rd / "run.json").read_text())
    assert info["skip_bad_demos"] is True
    assert len(info["demo_files_skipped"]) == 1 and str(bad) in info["demo_files_skipped"][0]
    from mimicrete import demos as mc_demos

    n_good = sum(len(mc_demos.load(str(f))) for f in sorted(demo_dir.glob("*.mcap")))
    assert info["demo_steps_loaded"] == n_good
    # a directory of only bad files, even with --skip-bad-demos
    only_bad = tmp_path / "bad_only"
    only_bad.mkdir()
    (only_bad / "x.mcap").write_bytes(bad.read_bytes())
    rc, _, err = run(_real_argv(tmp_path / "run-none", only_bad, "--skip-bad-demos"), capsys)
    assert rc == 2 and "no loadable demo file" in one_error_line(err, "train")


def test_skipping_reads_the_same_arrays_as_loading_the_directory(demo_dir, tmp_path):
    """Per-file loading (used only to skip bad files) gives exactly the directory's arrays."""
    from mimicrete import demos as mc_demos
    from mimicrete.learn.demo_data import _mcap_arrays, demo_arrays

    whole = demo_arrays(mc_demos.load(str(demo_dir)))
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    for f in demo_dir.glob("*.mcap"):
        (mixed / f.name).write_bytes(f.read_bytes())
    (mixed / "zz_bad.mcap").write_bytes(b"")
    parts, skipped = _mcap_arrays(mixed, skip_bad=True)
    assert len(skipped) == 1
    for k in whole:
        np.testing.assert_array_equal(parts[k], whole[k])
    assert math.isfinite(float(parts["obs"].sum()))
