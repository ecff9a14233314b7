"""Synthetic sweep run dirs (scalars.csv, eval files, run.json, trial.json) for the report's and
demos_needed's tests (``config``: a resolved_config.yaml)."""

from __future__ import annotations

import csv
import json
from pathlib import Path


def write_run(
    root: Path,
    group: int,
    seed: int,
    steps,
    installed,
    reward,
    gail=None,
    ev=None,
    status="done",
    wall=600.0,
    max_steps=None,
    error=None,
    extra_rows=(),
    ev_sampled=None,
    converged_at=None,
    config=None,
):
    from mimicrete.learn.run_files import TAGS

    rd = root / f"group{group}-seed{seed}"
    rd.mkdir(parents=True)
    with open(rd / "scalars.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["step", *TAGS])
        rows = list(
            zip(
                steps,
                installed,
                reward,
                gail if gail is not None else [None] * len(steps),
                strict=True,
            )
        ) + list(extra_rows)
        for s, ins, rew, gl in rows:
            row = {
                "Environment/Installed Rate": ins,
                "Environment/Cumulative Reward": rew,
                "Environment/Picked Rate": ins,
                "Losses/GAIL Loss": gl,
            }
            w.writerow([s, *["" if row.get(t) is None else repr(float(row[t])) for t in TAGS]])
    for name, e in (("eval.json", ev), ("eval_stochastic.json", ev_sampled)):
        if e is not None:
            (rd / name).write_text(
                json.dumps(
                    {
                        "episodes": 100,
                        "picked_rate": e[0],
                        "installed_rate": e[1],
                        "mean_episode_length": e[2],
                    }
                )
            )
    if config is not None:  # the resolved config as `mimicrete train` writes it
        import yaml

        (rd / "resolved_config.yaml").write_text(yaml.safe_dump(config))
    if converged_at is not None:
        (rd / "run.json").write_text(
            json.dumps({"convergence": {"installed_rate": 0.99, "converged_at_step": converged_at}})
        )
    (rd / "trial.json").write_text(
        json.dumps(
            {
                "group": group,
                "seed": seed,
                "status": status,
                "wall_clock_s": wall,
                "max_steps": max_steps or int(steps[-1]),
                "final_step": int(steps[-1]),
                "error": error,
            }
        )
    )
    return rd
