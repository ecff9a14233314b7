"""A training run: the run directory, resume, the loop of updates, summaries, checkpoints and the
final policy. ``train(cfg, run_dir)`` is what ``mimicrete train`` and the experiments sweep call.

Per update (``Trainer.iterate``, ``update.py``: rollout -> reward signals -> GAIL's discriminator
-> GAE -> PPO -> BC), then a summary row every ``summary_freq`` steps (CSV + TensorBoard) and a
checkpoint every ``checkpoint_interval`` steps and at the end. With ``stop_on_convergence`` the
run ends early once the summaries' installed rate has held its threshold ``summaries`` times in a
row; ``run.json`` then records the criterion and the step it was met at (``convergence``). After
the last update ``policy.pt`` and ``policy.onnx``. A non-finite loss stops the run
(``NonFiniteLossError``) before anything of that update is written, so the last checkpoint stays
the last good one.
"""

from __future__ import annotations

import dataclasses
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from . import config as config_mod
from . import run_files
from .trainer import Trainer

logger = logging.getLogger(__name__)


def train(
    cfg: config_mod.TrainerConfig,
    run_dir: str | Path,
    *,
    demos: str | None = None,
    resume: bool = False,
    force: bool = False,
    skip_bad_demos: bool = False,
    max_steps: int | None = None,
    progress: bool = True,
    stop_after_updates: int | None = None,
    log: Callable[[str], Any] | None = None,
) -> Trainer:
    """Run (or ``resume``) training in ``run_dir``; returns the trainer. A run dir holding another
    run is refused unless ``resume`` or ``force`` (which deletes that run's files first).
    ``stop_after_updates`` ends early without changing the schedules (for tests of resume).

    One process trains in a run dir at a time (``run_dir/.lock``, :func:`run_files.run_dir_lock`;
    a lock left by a killed process is taken over). Everything is checked before the first file is
    written (the run dir, the checkpoint to resume and that the config matches it, the demos), so
    refused input leaves the run dir as it was, and a run dir made for it is removed again.
    ``log`` gets the warnings (a damaged checkpoint passed over); default: this module's logger
    (``console.show_messages`` shows them as ``warning: ...`` on stderr)."""
    run_dir = Path(run_dir)
    run_files.require_onnx_exporter()
    created = _make_dirs(run_dir)
    try:
        with run_files.run_dir_lock(run_dir):
            return _train(
                cfg, run_dir, demos=demos, resume=resume, force=force,
                skip_bad_demos=skip_bad_demos, max_steps=max_steps, progress=progress,
                stop_after_updates=stop_after_updates, log=log or logger.warning,
            )  # fmt: skip
    finally:
        for d in reversed(created):  # only what is still empty: nothing was written
            try:
                d.rmdir()
            except OSError:
                break


def _make_dirs(path: Path) -> list[Path]:
    """``mkdir -p path``; the directories it created, outermost first."""
    missing = []
    p = path
    while not p.exists() and p != p.parent:
        missing.append(p)
        p = p.parent
    path.mkdir(parents=True, exist_ok=True)
    return list(reversed(missing))


def _train(
    cfg: config_mod.TrainerConfig,
    run_dir: Path,
    *,
    demos: str | None,
    resume: bool,
    force: bool,
    skip_bad_demos: bool,
    max_steps: int | None,
    progress: bool,
    stop_after_updates: int | None,
    log: Callable[[str], Any],
) -> Trainer:
    old_entries = run_files.check_run_dir(run_dir, resume=resume, force=force)
    total = int(max_steps if max_steps is not None else cfg.behavior.max_steps)
    state: dict[str, Any] | None = None
    if resume:
        ck, state = run_files.load_latest_intact(run_dir, log)
        _check_resumable(run_dir, ck, state, cfg, demos)
    # the trainer loads the demos first: a bad demo path leaves the run dir as it was
    tr = Trainer(cfg, run_dir, demos, total, skip_bad_demos=skip_bad_demos)
    run_files.clear_run_entries(run_dir, old_entries)  # --force
    config_mod.save(cfg, run_dir / "resolved_config.yaml")
    info: dict[str, Any] = {"max_steps": total, "demos": demos or cfg.demo_path}
    if resume:  # keep what the run recorded before (its warm start, for one)
        info = {**run_files.read_run_info(run_dir), **info}
    if tr.demos is not None:
        info["demo_steps_loaded"] = tr.demo_steps_loaded
        info["demo_steps_idle_dropped"] = tr.demo_steps_loaded - len(tr.demos.arrays["actions"])
    if skip_bad_demos:
        info["skip_bad_demos"] = True
        info["demo_files_skipped"] = tr.demo_files_skipped
    resume_step = None
    if state is not None:
        tr.load_state_dict(state)
        resume_step = tr.step
        del state
    else:
        warm = tr.pretrain()
        if warm is not None:
            info["bc_warm_start"] = warm
    conv = cfg.behavior.stop_on_convergence
    # a resumed run that had already converged stays converged (its streak is in the checkpoint)
    converged = conv is not None and tr.state.converged_streak >= conv.summaries
    if conv is not None and not converged:
        info["convergence"] = {**dataclasses.asdict(conv), "converged_at_step": None}
    run_files.write_run_info(run_dir, info)
    log_ = run_files.ScalarLog(run_dir, resume_step)
    bar = _progress_bar(total, tr.step) if progress else None
    ck_every = max(cfg.behavior.checkpoint_interval, 1)
    next_ck = (tr.step // ck_every + 1) * ck_every
    updates = 0
    try:
        while tr.step < total and not converged:
            before = tr.step
            tr.iterate()
            updates += 1
            st = tr.state
            if tr.step - st.last_summary_step >= cfg.behavior.summary_freq or tr.step >= total:
                row = tr.summary()
                if row:
                    log_.write(tr.step, row)
                st.last_summary_step = tr.step
                if conv is not None and _converged(tr, conv, row or {}):
                    info["convergence"] = {**dataclasses.asdict(conv), "converged_at_step": tr.step}
                    run_files.write_run_info(run_dir, info)
                    tr.save_checkpoint()
                    break
            if tr.step >= next_ck or tr.step >= total:
                tr.save_checkpoint()
                next_ck = (tr.step // ck_every + 1) * ck_every
            if bar is not None:
                bar.update(tr.step - before)
                bar.set_postfix(
                    picked=f"{st.recent_picked:.0%}", installed=f"{st.recent_installed:.0%}"
                )
            if stop_after_updates is not None and updates >= stop_after_updates:
                break
    finally:
        if bar is not None:
            bar.close()
        log_.close()
        tr.close()
    run_files.save_policy(run_dir, tr.state.actor, tr.obs_dim, tr.step, cfg)
    return tr


def _check_resumable(
    run_dir: Path,
    ck: Path,
    state: dict[str, Any],
    cfg: config_mod.TrainerConfig,
    demos: str | None,
) -> None:
    """Refuse (:class:`run_files.RunDirError`) a resume whose config or demos differ from the
    run's in anything that shapes it; only the budget, the checkpoints, the stop criterion and
    the thread settings may change (:data:`config.RESUME_MAY_CHANGE`)."""
    changes = config_mod.resume_changes(state["config"], cfg)
    before = run_files.read_run_info(run_dir).get("demos")
    now = demos or cfg.demo_path
    if before is not None and now is not None and before != now:
        if Path(before).resolve() != Path(now).resolve():
            changes.append(f"demos {config_mod.short_repr(before)} -> {config_mod.short_repr(now)}")
    if changes:
        shown = "; ".join(changes[:4]) + (
            f"; and {len(changes) - 4} more" if len(changes) > 4 else ""
        )
        raise run_files.RunDirError(
            f"--resume: {run_dir} was trained differently ({shown}, per {ck.name}); a resumed run "
            f"keeps what shapes it (it may change only {', '.join(config_mod.RESUME_MAY_CHANGE)}); "
            "start a new run with --force or another --run-dir"
        )


def _converged(tr: Trainer, conv: config_mod.ConvergenceSettings, row: dict[str, float]) -> bool:
    """Count this summary towards convergence; True once ``conv.summaries`` in a row held the
    installed rate over at least ``conv.min_episodes`` episodes (the streak is in checkpoints)."""
    ok = (
        row.get("Environment/Episodes", 0.0) >= conv.min_episodes
        and row.get("Environment/Installed Rate", 0.0) >= conv.installed_rate
    )
    tr.state.converged_streak = tr.state.converged_streak + 1 if ok else 0
    return tr.state.converged_streak >= conv.summaries


def _progress_bar(total: int, initial: int) -> Any:
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit="step",
        dynamic_ncols=True,
        file=sys.stderr,
        smoothing=0.1,
    )
