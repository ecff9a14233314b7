"""Export MCAP demos to the formats robot-learning code reads: LeRobot v3.0 and Minari.

    >>> from mimicrete import export
    >>> export.export("demos/suction", "lerobot", "exports/suction-lerobot")
    >>> export.export("demos/suction", "minari", "exports/minari")   # a Minari datasets root

One task per dataset (the tasks' action sizes differ). The input is read and checked once by
:func:`mimicrete.export.source.read_demo_dir` (every episode is replayed in the simulator);
:mod:`mimicrete.export.lerobot` writes the LeRobot files with pyarrow (no lerobot needed),
:mod:`mimicrete.export.minari` goes through ``minari.create_dataset_from_buffers``. Both write
the action with its effector command as a level, +1 / -1 held until the next command
(:mod:`mimicrete.export.levels`; the layout: docs/formats.md section 4).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from mimicrete.export.source import DemoEpisode, DemoSet, ExportError, read_demo_dir

__all__ = ["FORMATS", "DemoEpisode", "DemoSet", "ExportError", "Result", "export", "read_demo_dir"]

FORMATS: tuple[str, ...] = ("lerobot", "minari")


@dataclass(frozen=True)
class Result:
    """What an export wrote."""

    format: str
    out: Path
    task: str
    episodes: int
    frames: int
    dataset_id: str | None = None  # Minari only


def export(
    demos_dir: str | os.PathLike[str],
    fmt: str,
    out: str | os.PathLike[str],
    *,
    dataset_id: str | None = None,
    author: str | None = None,
) -> Result:
    """Export every demo of ``demos_dir`` (one task) as ``fmt`` into the new directory ``out``.

    Raises :class:`ExportError` (one line) for bad input: an unknown format, no demos, a damaged
    or unfinished demo, demos of several tasks, a demo that does not replay, an existing ``out``.
    """
    if fmt not in FORMATS:
        raise ExportError(f"unknown format {fmt!r}; known: {', '.join(FORMATS)}")
    if dataset_id is not None and fmt != "minari":
        raise ExportError("a dataset id is for --format minari only")
    from mimicrete.export.source import check_new_output

    check_new_output(out)  # fail before reading every demo
    ds = read_demo_dir(demos_dir)
    if fmt == "lerobot":
        from mimicrete.export import lerobot

        path = lerobot.write(ds, out)
        return Result(fmt, path, ds.task, len(ds.episodes), ds.num_frames)
    from mimicrete.export import minari

    path, did = minari.write(ds, out, dataset_id=dataset_id, author=author)
    return Result(fmt, path, ds.task, len(ds.episodes), ds.num_frames, did)
