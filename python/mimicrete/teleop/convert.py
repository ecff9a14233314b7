"""Hand logs → MCAP demonstrations: the teleoperation session (:mod:`.session`) run over files.

``mimicrete convert HANDLOG_OR_DIR --task suction --out DIR`` parses every hand log once up front
with the project's one hand-log parser (:func:`mimicrete.hands.parse`, Rust ``demo-log``;
``mimicrete.LogFormatError`` with ``file:line: reason`` on bad input), pushes its frames one by
one into a :class:`~mimicrete.teleop.session.Session` that records into an MCAP demo, and checks
the outcome: an episode in which the robot never followed the hand is a failure, not an empty
demo.

Output names are the input's whole name minus a known suffix (``.handlog.jsonl``, ``.jsonl``):
``take.v1.jsonl`` → ``take.v1.mcap``. Two inputs that would give one name, and demos that exist
already (unless ``overwrite``), are errors before anything is written. A lock file beside each
demo being written keeps two converters out of each other's files.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import _native, tasks
from mimicrete import gestures as gest
from mimicrete._native import MimicreteError, SimInputError
from mimicrete.hands import log as handlog
from mimicrete.hands.log import HandLogData
from mimicrete.kin import Calibration, parse_calibration
from mimicrete.safe_io import FileLock

from .provenance import ModelFileError, driving_of, model_of
from .record import DemoSink, episode_meta, source_keys
from .session import Counts, Session

#: Hand-log file suffixes stripped to name the demo (longest first).
LOG_SUFFIXES: tuple[str, ...] = (".handlog.jsonl", ".jsonl")


class ConvertError(MimicreteError, ValueError):
    """A hand log cannot become a demo (names the file and the reason)."""


@dataclass
class ConvertedEpisode:
    """The outcome of converting one hand log."""

    source: str
    out: str | None
    episode_seed: int
    steps: int
    rewards: list[float]
    actions: np.ndarray
    picked: bool
    installed: bool
    fell: bool
    terminated: bool
    truncated: bool
    counts: Counts


# ----------------------------------------------------------------------------------------------
# Inputs
# ----------------------------------------------------------------------------------------------


def calibration_of(log: HandLogData, source: str = "handlog") -> Calibration:
    """The calibration a log was recorded with (``extra.calibration``, validated), else the
    default for its space."""
    extra = log.header.get("extra") or {}
    cal = extra.get("calibration") if isinstance(extra, dict) else None
    if cal is not None:
        return parse_calibration(cal, source, 1, "extra.calibration")
    space = str(log.header.get("space", "openxr"))
    if space == "robot_base":
        return Calibration(np.eye(3), np.zeros(3), 1.0, "robot_base")
    return Calibration(space="openxr" if space in ("openxr", "webxr") else space)


def path_text(path: str | os.PathLike[str]) -> str:
    """A file name as text that can be printed and stored (JSON, MCAP metadata): bytes that are
    not UTF-8 (``take\\xff.jsonl`` on disk) are shown as ``\\xff`` instead of breaking every
    message and record that names the file."""
    return os.fsencode(path).decode("utf-8", "backslashreplace")


def load_log(path: str | os.PathLike[str], mode: str = "strict") -> HandLogData:
    """Parse a hand log for conversion (:func:`mimicrete.hands.parse`), with at least one
    frame. Raises ``mimicrete.LogFormatError`` (``file:line: reason``)."""
    log = handlog.parse(path, mode)
    _require_frames(log, os.fspath(path))
    return log


def _require_frames(log: HandLogData, source: str) -> None:
    if len(log) == 0:
        raise _native.log_format_error(source, 2, "no frames")


def find_logs(path: str | Path) -> list[Path]:
    """A hand log, or every ``*.jsonl`` in a directory (sorted)."""
    p = Path(path)
    if p.is_dir():
        logs = sorted(p.glob("*.jsonl"))
        if not logs:
            raise FileNotFoundError(f"{p}: no *.jsonl hand logs")
        return logs
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file or directory")
    return [p]


def demo_name(log_path: str | Path) -> str:
    """The demo file name of a hand log: its whole name minus a known suffix, plus ``.mcap``."""
    name = Path(log_path).name
    for suffix in LOG_SUFFIXES:
        if name.endswith(suffix) and len(name) > len(suffix):
            name = name[: -len(suffix)]
            break
    name = name.lstrip(".")
    if not name:
        raise ConvertError(f"{log_path}: cannot name a demo after this file")
    return name + ".mcap"


def plan_outputs(logs: list[Path], out_dir: Path, overwrite: bool) -> dict[Path, Path]:
    """Hand log → demo path, checked before anything is written: every name is unique, and
    existing demos are replaced only with ``overwrite``."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ConvertError(f"--out {out_dir}: exists and is not a directory")
    seen: dict[str, Path] = {}
    plan: dict[Path, Path] = {}
    for log in logs:
        name = demo_name(log)
        if name in seen:
            raise ConvertError(f"{seen[name]} and {log} would both be written as {name}")
        seen[name] = log
        plan[log] = out_dir / name
    existing = [p for p in plan.values() if p.exists()]
    if existing and not overwrite:
        shown = ", ".join(p.name for p in existing[:3]) + (" ..." if len(existing) > 3 else "")
        raise ConvertError(
            f"{out_dir}: {len(existing)} demo(s) exist already ({shown}); "
            "pass --overwrite to replace them"
        )
    return plan


def _Lock(path: Path) -> FileLock:  # noqa: N802 (was a class; the lock is mimicrete.safe_io's)
    """``PATH.lock`` held while one demo is written: a second converter writing the same demo is
    refused (a :class:`ConvertError`); a lock left by a killed process is taken over."""
    return FileLock(Path(str(path) + ".lock"), "this demo", ConvertError)


def out_dir_lock(out_dir: Path) -> FileLock:
    """``OUT/.lock`` held by one ``mimicrete convert`` for its whole run: a second convert into
    the same ``--out`` is refused before it plans anything (a :class:`ConvertError`)."""
    return FileLock(Path(out_dir) / ".lock", "this --out directory", ConvertError)


# ----------------------------------------------------------------------------------------------
# One log
# ----------------------------------------------------------------------------------------------


def spec_file_of(
    header: dict[str, Any],
    given: str | os.PathLike[str] | None,
    task: tasks.TaskSpec,
    source: str,
) -> tuple[str | None, dict[str, str]]:
    """The task spec file a log runs in (``given``, else the one its header names, else None:
    the built-in task) and the demo metadata naming it. Raises :class:`ConvertError` for a spec
    that is missing or bad, runs another task than ``task``, or differs from the one the log
    recorded."""
    extra = header.get("extra") if isinstance(header.get("extra"), dict) else {}
    path = os.fspath(given) if given is not None else extra.get("task_file")
    if path is None:
        return None, {}
    try:
        spec_task, spec = tasks.load_task_file(path)
    except (OSError, SimInputError) as e:
        raise ConvertError(f"{source}: task file {tasks.task_file_error(path, e)}") from None
    if spec_task.name != task.name:
        raise ConvertError(
            f"{source}: task file {path} runs the {spec_task.name} task, converting as {task.name}"
        )
    recorded = extra.get("task_spec")
    if recorded is not None and recorded != json.loads(json.dumps(spec)):
        raise ConvertError(
            f"{source}: task file {path} is not the spec the log was recorded with (it changed "
            "since; the log's header holds the spec as it was, extra.task_spec)"
        )
    return path, tasks.task_file_meta(path, spec)


def convert_log(
    log: HandLogData | str | os.PathLike[str],
    task: str,
    out: str | Path | None,
    *,
    source: str | os.PathLike[str] | None = None,
    episode_index: int = 0,
    model: gest.GestureModel | None = None,
    calibration: Calibration | None = None,
    task_file: str | os.PathLike[str] | None = None,
) -> ConvertedEpisode:
    """Run one hand log through a :class:`Session`; write its MCAP demo to ``out`` (a file path
    ending in ``.mcap``, a directory to write :func:`demo_name` into, or ``None``: simulate only).

    ``log`` is a hand-log path (parsed by :func:`load_log`) or an already parsed
    :class:`mimicrete.hands.HandLogData`; ``source`` names it (messages, metadata, as
    :func:`path_text`). The demo's ``source_handlog_sha256`` is the hash of the bytes the parser
    read (``log.report["sha256"]``), so it covers exactly what was converted.

    What reads the hand: ``model`` if given, else the gesture model the log's header names
    (``extra.gesture_model``, a live hand log: :func:`.provenance.model_of`, beside the log and
    checked by its SHA-256), else the shipped one for the task; ``calibration`` if given, else
    the log's ``extra.calibration``, else the default for its space. The demo's metadata says
    which (``gesture_model_from``, ``calibration_from``: ``given`` / ``handlog`` / ``default``).

    A log recorded for a task spec file (``extra.task_file``, ``synth-hands --task-file``) runs
    in that spec's env (``task_file`` if given, else the file the log names); the spec must be
    the one the log recorded (``extra.task_spec``), and the demo names it (``task_file``,
    ``task_spec``) and draws its scene.

    Raises:
        ConvertError: the log is for another task, the gesture model it names is missing, has
            changed (another SHA-256) or is not a model, its task spec file is missing, bad, of
            another task or changed since the log was recorded, or the robot never followed the
            hand.
    """
    if not isinstance(log, HandLogData):
        source = source if source is not None else log
        log = load_log(log)
    source_path = os.fspath(source) if source is not None else "handlog"
    source = path_text(source_path)
    _require_frames(log, source)
    spec = tasks.get(task)
    logged = log.header.get("task")
    if logged is not None:
        try:
            logged_task = tasks.get(str(logged)).name
        except ValueError:
            logged_task = str(logged)
        if logged_task != spec.name:
            raise ConvertError(
                f"{source}: hand log is for task {logged!r}, converting as {spec.name!r}"
            )
    seed = int(log.header.get("episode_seed") or 0)
    mapping, clutch = driving_of(log.header, len(log.t), source)
    spec_file, spec_extra = spec_file_of(log.header, task_file, spec, source)
    extra = log.header.get("extra")
    logged_cal = isinstance(extra, dict) and extra.get("calibration") is not None
    calib_from = "given" if calibration is not None else "handlog" if logged_cal else "default"
    calib = calibration if calibration is not None else calibration_of(log, source)
    model_from = "given"
    if model is None:
        try:
            model = model_of(log.header, source_path, source)
        except ModelFileError as e:
            raise ConvertError(str(e)) from None
        model_from = "handlog" if model is not None else "default"
        model = model or gest.load_default(spec.name)
    what_read = {
        "gesture_model_from": model_from,
        "calibration_from": calib_from,
        "calibration": calib.to_dict(),
    }
    if model.info.get("sha256"):
        what_read["gesture_model_sha256"] = model.info["sha256"]
    out_path = None
    if out is not None:
        out_path = Path(out)
        if out_path.suffix != ".mcap":
            out_path = out_path / demo_name(source_path)
    with _Lock(out_path) if out_path is not None else _nullcontext():
        sink = None
        rewards: list[float] = []
        actions: list[np.ndarray] = []
        try:  # from the first byte of the demo to its rename: an interruption leaves nothing
            if out_path is not None:
                meta = episode_meta(
                    episode=episode_index,
                    task_sim=spec.sim,
                    seed=seed,
                    source=None,  # source_keys below: relative to the demo, hashed as parsed
                    model=model,
                    layout=log.header["layout"],
                    space=log.header["space"],
                    handedness=log.header["handedness"],
                    extra={
                        "converter": "mimicrete convert",
                        "hand_rate_hz": _rate(log),
                        **what_read,
                        **spec_extra,
                    },
                )
                # the hash of the bytes parsed, not the file as it is now (it may have grown)
                meta.update(source_keys(source_path, out_path, log.report.get("sha256") or None))
                sink = DemoSink(out_path, meta, task_file=spec_file)
            session = Session(
                spec.name,
                log.header["layout"],
                log.header["handedness"],
                calib,
                seed,
                model=model,
                recorder=sink,
                mapping=mapping,
                task_file=spec_file,
            )
            skipped = 0  # frames after the end, never pushed
            for k in range(len(log.t)):
                frame = (float(log.t[k]), bool(log.tracked[k]), log.joints[k])
                for st in session.push(*frame, clutch=clutch.get(k)):
                    rewards.append(st.reward)
                    actions.append(st.action)
                if session.done:
                    skipped = len(log.t) - k - 1
                    break
            for st in session.finish():
                rewards.append(st.reward)
                actions.append(st.action)
            never = never_followed(session)
            if never is not None:
                raise ConvertError(f"{source}: the robot never followed the hand ({never})")
            counts = session.counts
            counts.frames_after_end += skipped
            if sink is not None:
                sink.close(session.installed, counts)
        except BaseException:
            if sink is not None:
                sink.abandon_quietly()
            if out_path is not None:  # ours while we hold the lock (even if the writer was
                Path(str(out_path) + ".partial").unlink(missing_ok=True)  # half made)
            raise
    return ConvertedEpisode(
        source,
        str(out_path) if out_path else None,
        seed,
        session.step_index,
        rewards,
        np.array(actions, dtype=np.float32).reshape(-1, spec.act_dim),
        session.picked,
        session.installed,
        session.fell,
        session.terminated,
        session.truncated,
        counts,
    )


def never_followed(session: Session) -> str | None:
    """Why the robot never followed the hand in a session, or None if it did at some step."""
    c = session.counts
    if session.target is not None:
        return None
    if c.frames == c.untracked:
        return f"all {c.frames} frames untracked"
    return f"no usable hand frame: {c.untracked} untracked, {c.degenerate} degenerate of {c.frames}"


class _nullcontext:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None


def replay(task: str, seed: int, actions: np.ndarray) -> list[float]:
    """Step a fresh environment reset with ``seed`` through ``actions``; its rewards."""
    env = _native.SimEnv(tasks.get(task).sim)
    env.reset(int(seed))
    out = []
    for a in np.asarray(actions, dtype=np.float32):
        _, r, term, trunc, _ = env.step(a)
        out.append(float(r))
        if term or trunc:
            break
    return out


def _rate(log: HandLogData) -> float:
    d = np.diff(log.t)
    d = d[d > 0]
    return float(1.0 / np.median(d)) if len(d) else 0.0
