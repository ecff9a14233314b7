"""One trial of the sweep = one training run in its own run dir, and its ``trial.json`` (what
happened to it: status, error, attempts, wall clock, budget; written by the trial, read by the
report). ``train_one`` calls the same library functions as ``mimicrete train`` + ``mimicrete eval``.
"""

from __future__ import annotations

import json
import os
import socket
import time
import traceback
from pathlib import Path
from typing import Any

from mimicrete.console import show_messages
from mimicrete.learn.run_files import latest_checkpoint

TRIAL_FILE = "trial.json"


def repo_root() -> Path:
    return Path(__file__).resolve().parents[3]


def run_dir_name(group: int, seed: int) -> str:
    return f"group{group}-seed{seed}"


def read_trial(run_dir: Path) -> dict[str, Any]:
    p = Path(run_dir) / TRIAL_FILE
    if not p.exists():
        return {}
    try:
        return json.loads(p.read_text())
    except json.JSONDecodeError:
        return {}


def write_trial(run_dir: Path, meta: dict[str, Any]) -> None:
    p = Path(run_dir) / TRIAL_FILE
    tmp = p.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(meta, indent=1))
    os.replace(tmp, p)


def _config_path(config_dir: str, group: int) -> Path:
    return Path(config_dir) / f"group{group}.yaml"


def train_one(
    *,
    group: int,
    seed: int,
    config_dir: str,
    run_root: str,
    max_steps: int,
    demos: str | None = None,
    num_envs: int | None = None,
    overrides: list[str] | None = None,
    eval_episodes: int = 100,
) -> dict[str, Any]:
    """Train (or continue, or skip when done) group ``group`` with ``seed`` in
    ``run_root/group<g>-seed<s>``; evaluate; return the final metrics. This is the adapter onto
    ``mimicrete.learn.train`` (the same steps as ``mimicrete train`` + ``mimicrete eval``).
    Exceptions propagate after being recorded in ``trial.json``."""
    import torch

    from mimicrete import learn
    from mimicrete.learn import config

    run_dir = Path(run_root) / run_dir_name(group, seed)
    run_dir.mkdir(parents=True, exist_ok=True)
    meta = read_trial(run_dir)
    if meta.get("max_steps") not in (None, max_steps):
        # the schedules decay over max_steps: a run dir cannot change budget half way
        raise ValueError(
            f"{run_dir} was trained with max_steps {meta['max_steps']}, this sweep asks for "
            f"{max_steps}: use another --out"
        )
    if meta.get("status") == "done" and (eval_episodes <= 0 or _evaluated(run_dir)):
        return _metrics(run_dir, meta)

    resume = latest_checkpoint(run_dir) is not None
    meta.update(
        group=group,
        seed=seed,
        config=str(_config_path(config_dir, group)),
        max_steps=max_steps,
        status="running",
        host=socket.gethostname(),
        attempts=int(meta.get("attempts", 0)) + 1,
        resumed_from_checkpoint=bool(meta.get("resumed_from_checkpoint")) or resume,
        error=None,
    )
    segments = list(meta.get("segments", []))
    if segments and segments[-1].get("seconds") is None:
        # the previous attempt was killed (e.g. the sweep was interrupted): its end is estimated
        # from the last write into the run dir (scalars.csv is appended at every summary)
        last = max(
            (
                p.stat().st_mtime
                for p in (run_dir / "scalars.csv", run_dir / TRIAL_FILE)
                if p.exists()
            ),
            default=segments[-1]["start"],
        )
        segments[-1]["seconds"] = max(0.0, last - segments[-1]["start"])
        segments[-1]["estimated"] = True
    t0 = time.time()
    segments.append({"start": t0, "seconds": None, "resumed": resume})
    meta["segments"] = segments
    write_trial(run_dir, meta)

    def _close_segment(status: str, error: str | None) -> None:
        segments[-1]["seconds"] = time.time() - t0
        meta["segments"] = segments
        meta["wall_clock_s"] = float(sum(s["seconds"] or 0.0 for s in segments))
        meta["status"] = status
        meta["error"] = error
        write_trial(run_dir, meta)

    try:
        cfg, _ = config.resolve(
            _config_path(config_dir, group),
            overrides=overrides,
            seed=seed,
            num_envs=num_envs,
            max_steps=max_steps,
        )
        torch.set_num_threads(max(1, cfg.torch_settings.num_threads))
        if demos is None and cfg.demo_path and not Path(cfg.demo_path).is_absolute():
            # Tune runs a trial in its own working dir: a relative demo_path means the repo's
            demos = str(repo_root() / cfg.demo_path)
        # a run dir without a checkpoint holds at most a crashed attempt's first rows: replaced
        tr = learn.train(cfg, run_dir, demos=demos, resume=resume, force=not resume, progress=False)
        meta["final_step"] = int(tr.step)
        learn.learning_curves(run_dir)
        if eval_episodes > 0:
            # deterministic (Table 5's column) and sampled (ML-Agents' default inference)
            for stochastic in (False, True):
                learn.evaluate_run(run_dir, eval_episodes, stochastic=stochastic)
    except BaseException as e:  # recorded, then re-raised so Tune marks the trial errored
        _close_segment("error", "".join(traceback.format_exception(e)))
        raise
    _close_segment("done", None)
    return _metrics(run_dir, meta)


def _evaluated(run_dir: Path) -> bool:
    from mimicrete.learn.evaluate import eval_file

    return all((run_dir / eval_file(s, False)).exists() for s in (False, True))


def _metrics(run_dir: Path, meta: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {
        "group": meta.get("group"),
        "seed": meta.get("seed"),
        "final_step": meta.get("final_step"),
        "wall_clock_s": meta.get("wall_clock_s"),
        "run_dir": str(run_dir),
    }
    ev = Path(run_dir) / "eval.json"
    if ev.exists():
        e = json.loads(ev.read_text())
        for k in ("picked_rate", "installed_rate", "mean_episode_length"):
            out[k] = e.get(k)
    return out


def tune_trainable(config: dict[str, Any]) -> None:
    """The function trainable: one training run, its final metrics reported once (the run's
    messages on the worker's stdout / stderr, which Ray shows)."""
    from ray import tune

    show_messages()

    metrics = train_one(**config)
    tune.report({k: v for k, v in metrics.items() if v is not None})
