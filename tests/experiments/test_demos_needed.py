"""The "demos needed" experiment end to end on a tiny budget: demos made through synth-hands +
convert, a fewdemo run, its evaluations (deterministic, sampled, robust, every checkpoint), the
table and the figure; a second call reuses the finished run."""

from __future__ import annotations

import json

from mimicrete.experiments import demos_needed as dn

from ._synthetic import write_run

TINY = [
    "behavior.hyperparameters.buffer_size=1024",
    "behavior.hyperparameters.batch_size=256",
    "behavior.network_settings.hidden_units=32",
    "behavior.network_settings.num_layers=2",
    "behavior.behavioral_cloning.pretrain_steps=5",
    "behavior.checkpoint_interval=1024",
    "behavior.summary_freq=1024",
    "env_settings.num_envs=8",
]


def test_demos_needed_tiny_run(tmp_path, capsys):
    out = tmp_path / "dn"
    sets = [a for s in TINY for a in ("--set", s)]
    argv = ["--counts", "2", "--seeds", "0", "--max-steps", "2048", "--episodes", "8",
            "--out", str(out), "--no-progress", *sets]  # fmt: skip
    assert dn.main(argv) == 0
    run = out / "suction-d2-s0"
    for f in ("eval.json", "eval_stochastic.json", "eval_robust.json", "checkpoint_evals.json"):
        assert (run / f).exists(), f
    cks = json.loads((run / "checkpoint_evals.json").read_text())
    assert [c["step"] for c in cks] == [1024, 2048] and all(c["episodes"] == 8 for c in cks)
    assert all(c["elapsed_s"] > 0 for c in cks)
    rows = json.loads((out / "summary.json").read_text())
    assert len(rows) == 1 and rows[0]["demos"] == 2 and rows[0]["max_steps"] == 2048
    row = rows[0]
    det = json.loads((run / "eval.json").read_text())
    assert row["installed"] == det["installed_rate"]
    if row["first_97_step"] is None:
        assert all(c["installed_rate"] < dn.TARGET for c in cks)
    md = (out / "summary.md").read_text()
    assert md.count("\n") == 3 and "| suction | 2 | 2k |" in md
    assert (out / "installed_vs_demos.png").stat().st_size > 5000
    assert len(list((out / "demos" / "suction-2").glob("*.mcap"))) == 2
    # the finished run is reused, not trained again; --paper-runs adds the paper's config
    mtime = (run / "policy.pt").stat().st_mtime
    capsys.readouterr()
    sweep = tmp_path / "sweep" / "runs"
    write_run(sweep, 9, 0, [10_000, 20_000], [0, 1], [0, 2], ev=(1.0, 0.5, 300))
    assert dn.main([*argv, "--paper-runs", str(sweep)]) == 0
    assert (run / "policy.pt").stat().st_mtime == mtime
    assert "suction 2 demos seed 0" in capsys.readouterr().out
    assert json.loads((out / "paper_config.json").read_text())[0]["installed"] == 0.5
    assert "| group 9 | 10 | 20k | 50% |" in (out / "summary.md").read_text()
    assert dn.main(argv) == 0  # later calls keep the paper's rows
    assert "| group 9 | 10 | 20k | 50% |" in (out / "summary.md").read_text()


def test_table_groups_seeds_per_count():
    rows = [
        {"task": "suction", "demos": 10, "seed": s, "max_steps": 300_000, "installed": 1.0,
         "picked": 0.9, "installed_stochastic": 0.9, "installed_robust": 0.3,
         "first_97_step": 153_600, "first_97_elapsed_s": 30.0 + s, "train_wall_clock_s": 60.0}
        for s in (1, 0)
    ]  # fmt: skip
    md = dn.table(rows)
    cells = "100% / 100% | 90% / 90% | 90% / 90% | 30% / 30% | 154k, 30 s / 154k, 31 s"
    assert f"| suction | 10 | 300k | {cells} |" in md


def test_bad_arguments_exit_2(tmp_path, capsys):
    assert dn.main(["--counts", "0", "--out", str(tmp_path)]) == 2
    assert "must be positive" in capsys.readouterr().err


def test_a_bad_config_is_one_line_before_any_demo_is_made(tmp_path, capsys):
    assert dn.main(["--config", str(tmp_path / "nope.yaml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"demos_needed: error: config {tmp_path / 'nope.yaml'} does not exist"
    assert not (tmp_path / "o" / "demos").exists()
    assert dn.main(["--set", "behavior.max_steps=-3", "--out", str(tmp_path / "o")]) == 2
    assert "max_steps: -3 is out of range" in capsys.readouterr().err


def test_the_papers_config_beside_ours_from_the_sweeps_run_dirs(tmp_path, capsys):
    """``--paper-runs``: groups 4, 8 and 9 of the sweep (two roots, as run in parts) in a second
    table; other groups and unevaluated runs are left out; a missing dir is one line, exit 2."""
    a, b = tmp_path / "table5" / "runs", tmp_path / "table5-5m" / "runs"
    steps = [10_000, 20_000]
    write_run(a, 4, 0, steps, [0.5, 1.0], [1, 2], ev=(1.0, 1.0, 60), ev_sampled=(1, 0.98, 61),
              converged_at=20_000, max_steps=1_000_000)  # fmt: skip
    write_run(a, 3, 0, steps, [0.5, 1.0], [1, 2], ev=(1.0, 1.0, 60))  # not a demo-count group
    write_run(b, 9, 0, steps, [0, 0], [0, 0], ev=(1.0, 0.0, 750), max_steps=20_000)
    write_run(b, 9, 1, steps, [0, 1], [0, 2], ev=(1.0, 0.5, 300), max_steps=20_000)
    write_run(b, 8, 0, steps, [0, 0], [0, 0], max_steps=20_000)  # still training: no eval
    rows = dn.paper_config_rows([a, b])
    assert sorted((r["group"], r["seed"]) for r in rows) == [(4, 0), (9, 0), (9, 1)]
    md = dn.paper_table(rows)
    assert md.splitlines()[2].startswith("| group 9 | 10 | 20k | 0% / 50% | – / – | 20k / 20k |")
    assert md.splitlines()[3].startswith("| group 4 | 60 | 1.00M | 100% | 98% | 20k c |")
    assert md.splitlines()[2].endswith("| 82% |") and md.splitlines()[3].endswith("| 97% |")
    assert dn.main(["--paper-runs", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip() == (
        f"demos_needed: error: --paper-runs {tmp_path / 'nope'}: no such directory"
    )
