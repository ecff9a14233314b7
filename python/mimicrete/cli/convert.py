"""`mimicrete convert`: hand logs → MCAP demonstrations (:mod:`mimicrete.teleop.convert`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mimicrete.cli import UsageError, calibration_arg, gesture_model_arg
from mimicrete.tasks import TASKS


def configure(parser: argparse.ArgumentParser) -> None:
    """Flags of ``mimicrete convert``."""
    parser.add_argument(
        "source", metavar="HANDLOG_OR_DIR", help="a hand log (.jsonl) or a directory of them"
    )
    parser.add_argument(
        "--task",
        required=True,
        choices=TASKS,
        help="the task the hand logs demonstrate",
    )
    parser.add_argument("--out", required=True, metavar="DIR", help="where the MCAP demos go")
    parser.add_argument(
        "--gesture-model",
        metavar="PATH",
        help="gesture model for every log (default: the one a live hand log names in its header, "
        "checked by its SHA-256; else the shipped one for the task)",
    )
    parser.add_argument(
        "--calibration",
        metavar="FILE.json",
        help="tracking space -> Base calibration for every log (default: the one a hand log "
        "carries, else the default for its space)",
    )
    parser.add_argument(
        "--task-file",
        metavar="SPEC.toml",
        help="run every log in this task spec file's env (default: the one a log recorded with "
        "synth-hands --task-file names in its header, else the built-in task); it must be the "
        "spec the log was recorded with",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace demos that exist in --out already"
    )
    parser.add_argument(
        "--lenient",
        action="store_true",
        help="skip bad and untracked frame lines instead of rejecting the log (the header must "
        "still be valid); the skipped lines are counted",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def main(args: argparse.Namespace) -> int:
    """Run ``mimicrete convert``; prints per-file outcomes and a summary. Every log is tried;
    exit 2 when logs were refused as bad input (malformed, not a regular file, for another task:
    each named on its own line; a live hand log whose gesture model is missing or changed, too),
    1 when any other failure (a disk error) stopped one."""
    from mimicrete.teleop import convert as cv

    logs = cv.find_logs(args.source)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: exists and is not a directory")
    made = not out.exists()
    try:
        lock = cv.out_dir_lock(out).acquire()  # one convert into --out at a time
    except cv.ConvertError as e:
        raise UsageError(str(e)) from None
    except OSError as e:
        raise UsageError(f"--out {out}: {e.strerror or e}") from None
    try:
        return _convert(args, cv, logs, out)
    finally:
        lock.release()
        if made:  # refused before writing anything: no empty --out left behind
            try:
                out.rmdir()
            except OSError:
                pass


def _convert(args: argparse.Namespace, cv: Any, logs: list[Path], out: Path) -> int:
    from tqdm import tqdm

    from mimicrete import LogFormatError

    try:
        plan = cv.plan_outputs(logs, out, args.overwrite)
    except cv.ConvertError as e:
        raise UsageError(str(e)) from None
    model = gesture_model_arg(args.gesture_model)
    calib = calibration_arg(args.calibration)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise UsageError(f"--out {out}: {e.strerror or e}") from None
    results = []
    failed = 0
    other_failures = 0
    mode = "lenient" if args.lenient else "strict"
    for i, path in enumerate(tqdm(logs, desc="convert", unit="log", disable=args.no_progress)):
        name = cv.path_text(path)
        try:
            log = cv.load_log(path, mode)
            res = cv.convert_log(
                log,
                args.task,
                plan[path],
                source=path,
                episode_index=i,
                model=model,
                calibration=calib,
                task_file=args.task_file,
            )
        except (LogFormatError, cv.ConvertError, ValueError, OSError) as e:
            failed += 1
            other_failures += not isinstance(e, (LogFormatError, cv.ConvertError))
            msg = str(e)
            tqdm.write(
                f"mimicrete convert: error: {msg if name in msg else f'{name}: {msg}'}",
                file=sys.stderr,
            )
            continue
        results.append(res)
        c = res.counts
        skipped = ""
        if args.lenient:
            skipped = f", {log.report.get('invalid_skipped', 0)} bad lines skipped"
        tqdm.write(
            f"{cv.path_text(path.name)}: {res.steps} steps, "
            f"{'installed' if res.installed else 'NOT installed'}"
            f"{', picked' if res.picked else ''}{', fell' if res.fell else ''}; frames "
            f"{c.frames} (untracked {c.untracked}, degenerate {c.degenerate}{skipped}), "
            f"unreachable {c.unreachable} steps, {c.gesture_changes} gesture changes"
        )
    n_ok = sum(r.installed for r in results)
    share = f" ({100.0 * n_ok / len(results):.1f} %)" if results else ""
    print(f"{len(results)} demos in {args.out}: {n_ok} installed{share}, {failed} logs failed")
    if failed == 0:
        return 0
    return 1 if other_failures else 2
