"""`mimicrete eval RUN_DIR --episodes 100 [--stochastic] [--starts training|robust|wide|FILE.jsonl]
[--map] [--video N]`: the paper's Table 5 row for a trained run and, for the simulator's tasks
but Screw, the placement table (where the object ended: held, height, xy and yaw error, the
lip-to-face gap of each hold, and the share the placed rule accepts), written to
``RUN_DIR/eval.json`` (``eval_stochastic.json`` for the sampled policy, ``eval_<starts>*.json``
from other starts; each episode's start, outcome and placement under ``per_episode``, the
placements' summary under ``placement``), with ``--map`` a heat map of success over the
table, and videos of the first N evaluation episodes in ``RUN_DIR/videos/``. Parses the flags and
calls ``mimicrete.learn.evaluate_run`` and ``mimicrete.learn.video.record_run_videos``."""

from __future__ import annotations

import argparse
from pathlib import Path

from mimicrete.cli import UsageError
from mimicrete.console import show_messages


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", help="a run directory written by `mimicrete train`")
    parser.add_argument("--episodes", type=int, default=100, help="episodes to run (100)")
    parser.add_argument("--seed", type=int, help="eval env seed (default: run seed + 10000)")
    parser.add_argument(
        "--stochastic",
        action="store_true",
        help="sample the policy (as ML-Agents runs a model without deterministic_inference) "
        "instead of taking its most likely action; writes RUN_DIR/eval_stochastic.json",
    )
    parser.add_argument(
        "--robust",
        action="store_true",
        help="start episodes wider than in training: the tile's x range widened by half on each "
        "side ([-0.075, 0.225] m) and the target moved by up to 2 cm; writes "
        "RUN_DIR/eval_robust.json (eval_robust_stochastic.json with --stochastic)",
    )
    parser.add_argument(
        "--starts",
        default="training",
        metavar="training|robust|wide|FILE.jsonl",
        help="where episodes start: training (the paper's, default), robust (as --robust), wide "
        "(the object over 0.25 x 0.10 m of table, turned up to 30 degrees, the target and its pad "
        "moved up to 4 cm; writes eval_wide.json), or a file of explicit starts, one JSON object "
        'a line: {"object_pose": [x, y, yaw], "target_offset": [dx, dy]} (m, rad; one episode per '
        "line, --episodes ignored; writes eval_starts-<stem>.json)",
    )
    parser.add_argument(
        "--map",
        action="store_true",
        help="also draw the installed rate over the tile's start x, y (a heat map of the episodes' "
        "starts) into RUN_DIR/<eval file's stem>_map.png",
    )
    parser.add_argument(
        "--video",
        type=int,
        default=0,
        metavar="N",
        help="also write videos of the first N evaluation episodes to RUN_DIR/videos/ (0)",
    )
    parser.add_argument(
        "--video-format",
        choices=["auto", "mp4", "gif"],
        default="auto",
        help="auto: mp4 where imageio-ffmpeg is installed, else an animated GIF",
    )


def main(args: argparse.Namespace) -> int:
    show_messages()  # the library's messages, if any
    run_dir = Path(args.run_dir)
    if args.episodes < 1:
        raise UsageError(f"--episodes: at least 1, got {args.episodes}")
    if args.seed is not None and args.seed < 0:
        raise UsageError(f"--seed: 0 or more, got {args.seed}")
    if args.video < 0:
        raise UsageError(f"--video: 0 or more, got {args.video}")
    if not run_dir.is_dir():
        raise UsageError(f"{run_dir}: no such run directory")
    import torch

    from mimicrete import learn
    from mimicrete.learn import video
    from mimicrete.learn.run_files import PolicyFileError, load_policy

    torch.set_num_threads(1)
    from mimicrete.learn import starts as starts_mod

    if args.robust and args.starts != "training":
        raise UsageError("--robust and --starts: give one of them")
    try:
        fmt = None
        es = load_policy(run_dir)[1].env_settings
        named = "robust" if args.robust else args.starts
        starts = starts_mod.resolve(named, es.env_id, es.task_file)
        if args.video:  # what would stop the videos, before the evaluation runs
            fmt = video.resolve_format(args.video_format)
            video.check_renderable(load_policy(run_dir)[1].env_settings.env_id)
        res = learn.evaluate_run(
            run_dir, args.episodes, args.seed, stochastic=args.stochastic, starts=starts
        )
    except (PolicyFileError, video.VideoError, ValueError) as e:
        raise UsageError(str(e)) from None
    print(learn.format_row(run_dir.name, res))
    if "placement" in res:  # the simulator's tasks but Screw
        print(learn.evaluate.format_placement(res["placement"]))
    print(f"starts: {res['starts']}, {res['episodes']} episodes, {res['policy']} policy")
    written = run_dir / learn.evaluate.eval_file(args.stochastic, starts=starts)
    print(f"wrote {written}")
    if args.map:
        from mimicrete.learn.plots import success_map

        eps = [e for e in res["per_episode"] if "object_pose" in e]
        if not eps:
            raise UsageError(f"--map: {es.env_id} episodes have no object start to draw")
        title = f"{run_dir.name}, {res['starts']}"
        word = learn.evaluate.success_word(es.env_id, es.task_file)
        out = success_map([(title, eps)], written.with_name(written.stem + "_map.png"), word=word)
        print(f"wrote {out}")
    if fmt is not None:
        try:
            episodes = video.record_run_videos(run_dir, args.video, args.seed, fmt)
        except video.VideoError as e:
            raise UsageError(str(e)) from None
        for ep in episodes:
            print(
                f"wrote {run_dir / video.VIDEO_DIR / ep.file}: seed {ep.episode_seed}, "
                f"{ep.length} steps, {ep.outcome}, {ep.frames} frames {ep.width}x{ep.height}"
            )
    return 0
