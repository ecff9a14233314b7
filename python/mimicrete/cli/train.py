"""`mimicrete train`: train a policy with BC + GAIL + PPO from a YAML config, then plot and
evaluate it. Parses the flags and calls ``mimicrete.learn`` (torch is imported in ``main``)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from mimicrete.cli import UsageError, task_file_arg
from mimicrete.console import show_messages
from mimicrete.learn.config import DEFAULT_DEMOS, DEFAULT_GROUP, DEFAULT_MAX_STEPS  # no torch


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config",
        help=f"ML-Agents-shaped YAML (default configs/{DEFAULT_GROUP}"
        f" with --max-steps {DEFAULT_MAX_STEPS})",
    )
    parser.add_argument(
        "--demos",
        help="demo dir/file; overrides the config's demo_path "
        f"(default: the config's, i.e. {DEFAULT_DEMOS})",
    )
    parser.add_argument(
        "--make-demos",
        action="store_true",
        help="if the demo path holds too few demos, make them first (synth-hands + convert, as "
        "`make demos`; for a config whose behavioral_cloning names generate_from, then `mimicrete "
        "demogen` from those at the wide starts); what `python train.py` does",
    )
    parser.add_argument(
        "--skip-bad-demos",
        action="store_true",
        help="train on the loadable demo files of a directory, listing the bad ones in run.json "
        "(default: a bad file is an error)",
    )
    parser.add_argument(
        "--task-file",
        metavar="SPEC.toml",
        help="train and evaluate in the task this spec file describes (sets env_settings.env_id "
        "Task-v0 and env_settings.task_file; its demos must be recorded in that spec: "
        "synth-hands / teleop / convert --task-file)",
    )
    parser.add_argument("--run-dir", help="default runs/<config name>-seed<seed>")
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--resume", action="store_true", help="continue from the latest checkpoint")
    group.add_argument(
        "--force", action="store_true", help="replace the run already in --run-dir (deletes it)"
    )
    parser.add_argument("--seed", type=int, help="override env_settings.seed")
    parser.add_argument("--max-steps", type=int, help="override max_steps (schedules follow it)")
    parser.add_argument("--num-envs", type=int, help="override env_settings.num_envs")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override any config key, e.g. behavior.reward_signals.gail."
        "survivor_bias=none (repeatable)",
    )
    parser.add_argument(
        "--eval-episodes",
        type=int,
        default=100,
        help="evaluate the final policy on this many episodes (0: skip)",
    )
    parser.add_argument(
        "--stop-on-convergence",
        action="store_true",
        help="stop before max_steps once the training episodes installed >= 99 %% in 3 summaries "
        "in a row (>= 20 episodes each; the config's stop_on_convergence if it has one); "
        "run.json records the criterion and the step (what `python train.py` passes)",
    )
    parser.add_argument(
        "--compare",
        metavar="POLICY",
        help="also evaluate this policy (a run dir or its policy.pt) on the same starts, print its "
        "rows and draw both success maps into RUN_DIR/success_map.png (`python train.py` passes "
        "the paper's recipe, tests/learn/data/group3_policy.pt)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    from mimicrete import learn
    from mimicrete.learn import config

    show_messages()  # the library's messages (demos being made, a checkpoint passed over)
    if args.eval_episodes < 0:
        raise UsageError(f"--eval-episodes: 0 or more, got {args.eval_episodes}")
    config_file = args.config
    if args.resume and config_file is None and args.run_dir:
        # a run continues with the config it was trained with (not the default one)
        resolved = Path(args.run_dir) / "resolved_config.yaml"
        if resolved.is_file():
            config_file = str(resolved)
    overrides = list(args.set or [])
    if args.task_file is not None:
        spec_task = task_file_arg(args.task_file, None)  # read and checked: one line if bad
        _check_config_task(config, config_file, overrides, spec_task, args.task_file)
        overrides += ["env_settings.env_id=Task-v0", f"env_settings.task_file={args.task_file}"]
    try:
        cfg, cfg_path = config.resolve(
            config_file,
            overrides=overrides,
            seed=args.seed,
            num_envs=args.num_envs,
            max_steps=args.max_steps,
        )
    except learn.ConfigError as e:
        raise UsageError(str(e)) from None
    if args.stop_on_convergence and cfg.behavior.stop_on_convergence is None:
        cfg.behavior.stop_on_convergence = config.ConvergenceSettings()
    run_dir = Path(args.run_dir) if args.run_dir else config.default_run_dir(cfg_path, cfg)
    demos = args.demos or cfg.demo_path
    compare = _compare_source(args.compare, cfg.env_settings.env_id, cfg.env_settings.task_file)
    bc = cfg.behavior.behavioral_cloning
    # the demos --make-demos makes are the config's task's (the scripted person's, built in)
    demo_task = _demo_task(cfg.env_settings.env_id)
    if args.make_demos and demos and bc is not None and bc.generate_from and not args.demos:
        learn.ensure_generated_demos(
            Path(demos),
            bc.generate_count or 0,
            Path(bc.generate_from),
            bc.generate_sources or 0,
            task=demo_task,
            speed=bc.generate_speed,
        )
    elif args.make_demos and demos:
        learn.ensure_demos(Path(demos), cfg.behavior.demo_episodes or 1, task=demo_task)
    t0 = time.perf_counter()
    try:
        tr = learn.train(
            cfg,
            run_dir,
            demos=args.demos,
            resume=args.resume,
            force=args.force,
            skip_bad_demos=args.skip_bad_demos,
            progress=not args.no_progress,
        )
    except (learn.ConfigError, learn.DemoDataError, learn.RunDirError) as e:
        raise UsageError(str(e)) from None
    print(f"trained {tr.step} steps in {time.perf_counter() - t0:.0f} s -> {run_dir}")
    conv = learn.run_files.read_run_info(run_dir).get("convergence") or {}
    if conv.get("converged_at_step") is not None:
        print(
            f"converged at step {conv['converged_at_step']}: installed >= "
            f"{conv['installed_rate']:.0%} in {conv['summaries']} summaries in a row"
        )
    for skipped in tr.demo_files_skipped:
        print(f"skipped demo: {skipped}")
    for p in learn.learning_curves(run_dir):
        print(f"plot: {p}")
    if args.eval_episodes > 0:
        compared = _compare_dir(run_dir, compare)
        print(_eval_rows(run_dir, args.eval_episodes, Path(cfg_path).stem, compared))
    return 0


def _demo_task(env_id: str) -> str:
    """The task (``suction``, ``place`` …) whose demos ``--make-demos`` makes for a config of
    ``env_id``: its built-in task, else (the toy env, a spec file's ``Task-v0``) ``suction``, as
    before configs of other tasks made their own."""
    from mimicrete import tasks

    try:
        return tasks.get(env_id).name
    except ValueError:
        return "suction"


def _check_config_task(
    config: Any, config_file: str | None, overrides: list[str], spec_task: str, task_file: str
) -> None:
    """``--task-file`` replaces the config's env: the config must be one for the task the spec
    runs (its env_id that task's, or Task-v0), else a :class:`UsageError` naming both."""
    from mimicrete import learn, tasks
    from mimicrete.learn.env import sim_task_of

    try:
        env_id = config.resolve(config_file, overrides=overrides)[0].env_settings.env_id
    except learn.ConfigError as e:
        raise UsageError(str(e)) from None
    ours = tasks.get(spec_task).sim
    if env_id.split("/")[-1] != "Task-v0" and sim_task_of(env_id) != ours:
        raise UsageError(
            f"--task-file {task_file} runs {ours}, but the config trains {env_id}; "
            f"give a config for {ours} (its env_id {ours}-v0)"
        )


def _compare_source(
    policy: str | None, env_id: str, task_file: str | None = None
) -> Path | None:
    """The policy.pt ``--compare`` names (a run dir's or the file given), checked up front: a
    readable policy of the task this run trains (``env_id``, ``task_file``)."""
    if policy is None:
        return None
    from mimicrete.learn.env import sim_task_of
    from mimicrete.learn.run_files import PolicyFileError, load_policy_file

    p = Path(policy)
    src = p / "policy.pt" if p.is_dir() else p
    if not src.is_file():
        raise UsageError(f"--compare {p}: no such policy file or run directory with a policy.pt")
    try:
        es = load_policy_file(src)[1].env_settings
    except PolicyFileError as e:
        raise UsageError(f"--compare {e}") from None
    theirs = sim_task_of(es.env_id, es.task_file) or es.env_id
    ours = sim_task_of(env_id, task_file) or env_id
    if theirs != ours:
        raise UsageError(
            f"--compare {src}: a policy of {theirs}, but this run trains {ours}; "
            "compare policies of the same task"
        )
    return src


def _compare_dir(run_dir: Path, src: Path | None) -> Path | None:
    """``RUN_DIR/compare/<name>/``, holding a copy of the compared policy: its evaluation files
    are kept with the run and never overwrite the compared run's own."""
    if src is None:
        return None
    import shutil

    d = run_dir / "compare" / (src.parent.name if src.name == "policy.pt" else src.stem)
    d.mkdir(parents=True, exist_ok=True)
    shutil.copy(src, d / "policy.pt")
    return d


def _paper_row(name: str) -> tuple[str, dict] | None:
    """The paper's Table 5 row for a paper group's name (``group3``, ``group3_policy``)."""
    from mimicrete.experiments.paper import PAPER_TABLE5

    digits = name[5:6] if name.startswith("group") else ""
    if not digits.isdigit() or int(digits) not in PAPER_TABLE5:
        return None
    p, i, n = PAPER_TABLE5[int(digits)]
    row = {"picked_rate": p, "installed_rate": i, "mean_episode_length": n}
    return f"paper, group {digits} (Table 5)", row


def _eval_rows(run_dir: Path, episodes: int, config_stem: str, compare: Path | None) -> str:
    """Table 5's row of the final policy on the training starts and, for the simulator's tasks,
    on the wide starts (the eval files say which), with the paper's row for a paper group; the
    same for the ``compare`` policy, and both success maps over the wide starts. Under the rows,
    the trained policy's placement tables (where its objects ended; not Screw's)."""
    from mimicrete import learn
    from mimicrete.learn.env import sim_task_of
    from mimicrete.learn.plots import success_map
    from mimicrete.learn.run_files import load_policy

    es = load_policy(run_dir)[1].env_settings
    sim = sim_task_of(es.env_id) is not None
    rows: list[tuple[str, dict]] = []
    maps = []
    seed = _eval_seed(run_dir)
    marked = None
    placements = []
    for rd in [run_dir] if compare is None else [run_dir, compare]:
        own = learn.evaluate_run(rd, episodes, seed)
        rows.append((f"{rd.name}, training starts", own))
        if sim and marked is None:
            marked = [e["object_pose"] for e in own["per_episode"]]
        results = [("training starts", own)]
        if sim:
            wide = learn.evaluate_run(rd, episodes, seed, starts="wide")
            rows.append((f"{rd.name}, wide starts", wide))
            maps.append((f"{rd.name}, wide starts", wide["per_episode"]))
            results.append(("wide starts", wide))
        if rd == run_dir:
            placements = [(where, r["placement"]) for where, r in results if "placement" in r]
    for name in dict.fromkeys([config_stem] + ([compare.name] if compare else [])):
        paper = _paper_row(name)
        if paper is not None:
            rows.append(paper)
    table = learn.format_rows(rows)
    for where, summary in placements:
        table += f"\n{run_dir.name}, {where}:\n" + learn.evaluate.format_placement(summary)
    if maps:
        word = learn.evaluate.success_word(es.env_id, es.task_file)
        out = success_map(maps, run_dir / "success_map.png", marked=marked, word=word)
        table += f"\nplot: {out} ({word} rate over the tile's start x, y; wide starts)"
    return table


def _eval_seed(run_dir: Path) -> int:
    """The trained run's evaluation seed: a compared policy runs the very same starts."""
    from mimicrete.learn.run_files import load_policy

    return load_policy(run_dir)[1].env_settings.seed + 10_000
