"""`mimicrete export`: MCAP demos → a LeRobot v3.0 or Minari dataset (:mod:`mimicrete.export`)."""

from __future__ import annotations

import argparse

from mimicrete.cli import UsageError


def configure(parser: argparse.ArgumentParser) -> None:
    """Flags of ``mimicrete export``."""
    parser.add_argument(
        "demos", metavar="DEMOS_DIR", help="a folder of MCAP demos, all of one task"
    )
    parser.add_argument(
        "--format", required=True, choices=["lerobot", "minari"], help="the dataset format"
    )
    parser.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="a new directory: the LeRobot dataset root, or the Minari datasets root "
        "(MINARI_DATASETS_PATH) the dataset is written under",
    )
    parser.add_argument(
        "--dataset-id",
        metavar="ID",
        help="Minari dataset id (default mimicrete/<TileSuction|BlockGrip|Screw|TileRow>/demos-v0)",
    )
    parser.add_argument("--author", help="Minari: the dataset's author")


def main(args: argparse.Namespace) -> int:
    """Run ``mimicrete export``; prints what was written and how to load it."""
    from mimicrete.export import ExportError, export

    try:
        res = export(
            args.demos, args.format, args.out, dataset_id=args.dataset_id, author=args.author
        )
    except ExportError as e:
        raise UsageError(str(e)) from None
    print(
        f"{res.episodes} episodes, {res.frames} frames of task {res.task} -> {res.format} "
        f"dataset in {res.out}"
    )
    if res.format == "lerobot":
        print(
            f"load: LeRobotDataset('local/{res.task}', root='{res.out}')  "
            "(set HF_HUB_OFFLINE=1 to keep lerobot off the network)"
        )
    else:
        print(f"load: MINARI_DATASETS_PATH={res.out} minari.load_dataset('{res.dataset_id}')")
    return 0
