"""The survivor-bias table from run dirs: handling and budget read from each run's own files,
comparison runs and the sweep's runs side by side, a missing dir one line through the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from mimicrete.experiments import survivor


def _run(root: Path, name: str, bias: str | None, max_steps: int, det, sam) -> None:
    d = root / name
    d.mkdir(parents=True)
    gail = {"strength": 0.1} if bias is None else {"strength": 0.1, "survivor_bias": bias}
    cfg = {"behaviors": {"TileSuction": {"max_steps": max_steps,
                                         "reward_signals": {"gail": gail}}}}  # fmt: skip
    (d / "resolved_config.yaml").write_text(yaml.safe_dump(cfg))
    for f, (p, i, length) in (("eval.json", det), ("eval_stochastic.json", sam)):
        if p is not None:
            ev = {"picked_rate": p, "installed_rate": i, "mean_episode_length": length}
            (d / f).write_text(json.dumps(ev))


def test_table_of_both_handlings_beside_the_paper(tmp_path, capsys):
    comp, sweep = tmp_path / "survivor", tmp_path / "table5" / "runs"
    _run(comp, "group5-none-seed0", "none", 5_000_000, (0, 0, 750), (0.93, 0.01, 744))
    _run(comp, "group5-none-seed1", "none", 5_000_000, (0.4, 0, 750), (0.87, 0.0, 750))
    _run(
        comp, "group5-none-seed2", "none", 5_000_000, (0, 0, 750), (None, None, None)
    )  # no sampled
    _run(sweep, "group5-seed0", "bootstrap", 1_000_000, (0, 0, 750), (1.0, 0.4, 500))
    _run(sweep, "group3-seed0", "bootstrap", 1_000_000, (1, 1, 60), (1, 1, 60))  # not 2, 5, 7
    _run(sweep, "group7-seed0", None, 1_000_000, (0, 0, 700), (0.9, 0.2, 600))  # the default: none
    rows = survivor.load([comp, sweep])
    assert sorted((r["group"], r["seed"], r["survivor_bias"]) for r in rows) == [
        (5, 0, "bootstrap"), (5, 0, "none"), (5, 1, "none"), (7, 0, "none")
    ]  # fmt: skip
    lines = survivor.table(rows).splitlines()
    assert lines[0].startswith("| group | survivor bias | steps | n |") and len(lines) == 5
    assert lines[2] == (
        "| 5 | `bootstrap` | 1.00M | 1 | 0 % | 0 % | 100 % (100 %) | 40 % (40 %) | 500 | "
        "93 % / 0 % / 712 |"
    )
    assert lines[3] == (
        "| 5 | `none` | 5.00M | 2 | 0 / 40 % | 0 / 0 % | 90 ± 4 % (93 / 87 %) | 0 ± 1 % (1 / 0 %) "
        "| 747 ± 4 | 93 % / 0 % / 712 |"
    )
    assert lines[4].startswith("| 7 | `none` | 1.00M | 1 |") and lines[4].endswith(
        "| 27 % / 0 % / 672 |"
    )
    out = tmp_path / "t.md"
    assert survivor.main(["--runs", str(comp), str(sweep), "--out", str(out)]) == 0
    assert out.read_text() == survivor.table(rows) == capsys.readouterr().out
    assert survivor.main(["--runs", str(tmp_path / "nope")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"survivor: error: --runs {tmp_path / 'nope'}: no such directory"
