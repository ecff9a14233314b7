"""MCAP demonstrations: load them into numpy arrays, write them, salvage cut ones, inspect them.

The file format (one MCAP file per episode; channels ``/demo/step``, ``/hand/joints``, ``/tf``,
``/scene``, ``/events``; metadata records ``episode_start`` / ``episode``; the URDF attached) is
described in ``docs/formats.md``. The work is done by the Rust crate ``demo-log`` through
``mimicrete._native``; ``inspect`` reads the summary with the official ``mcap`` Python reader, so
the CLI doubles as an independent check, and ``verify`` (Rust) checks every chunk's CRC.

    >>> d = mc.demos.load("demos/")          # every *.mcap in the directory, sorted by name
    >>> d.obs.shape, d.actions.shape, d.episode[:3]
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import _native

__all__ = [
    "STEP_DTYPES",
    "Demos",
    "files",
    "inspect",
    "load",
    "read",
    "recorded_start",
    "salvage",
    "salvage_to",
    "step_arrays",
    "verify",
]

STEP_TOPIC = "/demo/step"
#: A live demo's per-step stage times (docs/formats.md §2; written by ``mimicrete teleop``).
STAGE_TIMES_TOPIC = "/teleop/stage_times"
#: The per-step arrays of :class:`Demos` (and of a demo ``.npz``) and their dtypes.
STEP_DTYPES: dict[str, Any] = {
    "obs": np.float32,
    "actions": np.float32,
    "rewards": np.float32,
    "terminated": bool,
    "truncated": bool,
    "episode": np.int64,
}


def recorded_start(meta: Mapping[str, str]) -> dict[str, Any] | None:
    """The explicit start a demo's episode metadata records (a generated demo's: ``object_pose``,
    ``target_offset`` and a turned pad's ``pad_yaw``, what ``SimVecEnv.reset_replay`` and the gym
    reset options take), None for a demo that starts at its seed's own start."""
    if "object_pose" not in meta:
        return None
    keys = ("object_pose", "target_offset", "pad_yaw")
    return {k: json.loads(meta[k]) for k in keys if k in meta}


def step_arrays(rows: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Per-step values (a sequence for each key of :data:`STEP_DTYPES`) as the arrays
    :func:`load` gives, with its dtypes."""
    return {k: np.asarray(rows[k], dtype) for k, dtype in STEP_DTYPES.items()}


def _writer_class() -> Any:
    try:
        return _native.DemoWriter
    except AttributeError as e:  # the native module was built without demo-log
        raise ImportError(
            "mimicrete._native was built without the demo-log bindings "
            "(crates/pyext needs its demo-log dependency); rebuild with `make native`"
        ) from e


def __getattr__(name: str) -> Any:  # ``DemoWriter``: the native class, looked up lazily
    if name == "DemoWriter":
        return _writer_class()
    raise AttributeError(f"module 'mimicrete.demos' has no attribute {name!r}")


@dataclass
class Demos:
    """Demonstration steps of one or more episodes, concatenated in file order.

    ``obs`` (N, obs_dim) float32, ``actions`` (N, act_dim) float32, ``rewards`` (N,) float32,
    ``terminated`` / ``truncated`` (N,) bool, ``episode`` (N,) int64 (index into ``files``),
    ``files`` the demo paths, ``metas`` each file's ``episode`` metadata record (str -> str).
    """

    obs: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    episode: np.ndarray
    files: list[str] = field(default_factory=list)
    metas: list[dict[str, str]] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.rewards.shape[0])

    def __getitem__(self, key: str) -> Any:  # dict-style access: d["obs"]
        return getattr(self, key)

    @property
    def num_episodes(self) -> int:
        return len(self.files)

    def episode_slices(self) -> list[slice]:
        """Row range of each episode (episodes with no steps give empty slices)."""
        counts = np.bincount(self.episode, minlength=len(self.files))
        ends = np.cumsum(counts)
        return [slice(int(e - c), int(e)) for c, e in zip(counts, ends, strict=True)]


def load(path_or_dir: str | os.PathLike[str]) -> Demos:
    """Load one demo file, or every ``*.mcap`` in a directory (sorted by name; ``*.partial`` files
    are skipped), into flat arrays. Raises ``mimicrete.LogFormatError`` for a malformed or cut
    file (``salvage_to`` repairs a cut one) and ``OSError`` if it cannot be read."""
    d = _native.demo_load(os.fspath(path_or_dir))
    return Demos(
        obs=d["obs"],
        actions=d["actions"],
        rewards=d["rewards"],
        terminated=d["terminated"],
        truncated=d["truncated"],
        episode=d["episode"],
        files=[os.fspath(f) for f in d["files"]],
        metas=list(d["metas"]),
    )


def files(directory: str | os.PathLike[str]) -> list[Path]:
    """The ``*.mcap`` entries of a directory, sorted by name (``*.partial`` files never match),
    as :func:`load` reads them: every entry with the name, so that one that is not a demo file
    (a dangling symbolic link, a named pipe) is refused by name when it is read, never skipped."""
    return [Path(f) for f in _native.demo_files(os.fspath(directory))]


def _regular_file(path: Path) -> None:
    """Refuse, by name, what is not a regular file before opening it (opening a named pipe
    blocks until a writer comes); the Rust readers make the same check
    (``demo_log::read_input``)."""
    import stat

    try:
        st = os.stat(path)
    except FileNotFoundError:
        if path.is_symlink():
            raise _native.log_format_error(
                str(path),
                None,
                f"dangling symbolic link (its target {os.readlink(path)!r} does not exist)",
            ) from None
        raise
    if not stat.S_ISREG(st.st_mode):
        kinds = [
            (stat.S_ISFIFO, "a named pipe"),
            (stat.S_ISSOCK, "a socket"),
            (stat.S_ISCHR, "a character device"),
            (stat.S_ISBLK, "a block device"),
            (stat.S_ISDIR, "a directory"),
        ]
        kind = next((k for test, k in kinds if test(st.st_mode)), "something else")
        raise _native.log_format_error(str(path), None, f"not a regular file ({kind})")


def read(path: str | os.PathLike[str]) -> dict[str, Any]:
    """One episode: dict obs, actions, rewards, terminated, truncated, t (s) and meta."""
    return dict(_native.demo_read(os.fspath(path)))


def salvage(path: str | os.PathLike[str]) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Every message of every intact chunk of a (possibly cut or damaged) demo, wherever the
    damage is, and a report (chunks_ok, chunks_lost, lost_chunks, messages, step_gaps,
    bytes_used, complete, stopped_because, ...)."""
    msgs, report = _native.demo_salvage(os.fspath(path))
    return list(msgs), dict(report)


def salvage_to(path_in: str | os.PathLike[str], path_out: str | os.PathLike[str]) -> dict[str, Any]:
    """Rewrite what can be recovered from ``path_in`` as a complete demo ``path_out`` that
    ``load`` accepts: its ``salvage`` metadata record declares the lost steps (``step_gaps``,
    ranges ``a..b``), the row before each gap is marked truncated, and ``load(...).metas`` carry
    the record as ``salvage.<key>``."""
    return dict(_native.demo_salvage_to(os.fspath(path_in), os.fspath(path_out)))


def verify(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Check a demo's integrity: every chunk's CRC, the data-section and summary CRCs, and that
    the file is complete. Returns ok, chunks (index, offset, length, messages, log_time_start,
    log_time_end, error, recoverable), skipped byte ranges, data_crc_ok, summary_problem,
    messages_ok, messages_lost and problems (one line each; empty when healthy). Raises
    ``mimicrete.LogFormatError`` for a file that is not MCAP at all."""
    return dict(_native.demo_verify(os.fspath(path)))


# ---- inspect -------------------------------------------------------------------------------


def inspect(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What is in a demo, read from its summary with the official ``mcap`` reader: channels with
    schema, encoding and message count, metadata records, attachments, start/end log time,
    duration, steps and success. A cut file raises ``mimicrete.LogFormatError`` naming salvage;
    so does an MCAP file without a ``/demo/step`` channel (not a mimicrete demo) and a path that
    is not a regular file (a named pipe would block).
    The summary says nothing about the chunks' integrity: ``verify`` checks every chunk's CRC
    (``mimicrete inspect`` runs both)."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    p = Path(path)
    _regular_file(p)
    with p.open("rb") as f:
        try:
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
            if summary is None:
                raise _native.log_format_error(
                    str(p), None, "no summary section (cut file?); try `mimicrete.demos.salvage_to`"
                )
            stats = summary.statistics
            counts = stats.channel_message_counts if stats else {}
            channels = []
            for cid, ch in sorted(summary.channels.items()):
                schema = summary.schemas.get(ch.schema_id)
                channels.append(
                    {
                        "topic": ch.topic,
                        "schema": schema.name if schema else "",
                        "schema_encoding": schema.encoding if schema else "",
                        "message_encoding": ch.message_encoding,
                        "messages": int(counts.get(cid, 0)),
                        "metadata": dict(ch.metadata),
                    }
                )
            metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            stage_times, stages_error = _stage_times(reader, channels)
            attachments = [
                {"name": a.name, "media_type": a.media_type, "bytes": len(a.data)}
                for a in reader.iter_attachments()
            ]
        except McapError as e:
            raise _native.log_format_error(
                str(p), None, f"{e}; try `mimicrete.demos.salvage_to`"
            ) from e
    start = int(stats.message_start_time) if stats else 0
    end = int(stats.message_end_time) if stats else 0
    if not any(c["topic"] == STEP_TOPIC for c in channels):
        topics = ", ".join(sorted({c["topic"] for c in channels})) or "none"
        raise _native.log_format_error(
            str(p), None, f"not a mimicrete demo: no {STEP_TOPIC} channel (its topics: {topics})"
        )
    ep = metadata.get("episode") or metadata.get("episode_start") or {}
    steps = next((c["messages"] for c in channels if c["topic"] == STEP_TOPIC), 0)
    return {
        "path": str(p),
        "bytes": p.stat().st_size,
        "channels": channels,
        "messages": int(stats.message_count) if stats else 0,
        "chunks": int(stats.chunk_count) if stats else 0,
        "start_ns": start,
        "end_ns": end,
        "duration_s": (end - start) / 1e9,
        "steps": steps,
        "success": {"true": True, "false": False}.get(ep.get("success", ""), None),
        "finished": "episode" in metadata,
        "metadata": metadata,
        "attachments": attachments,
        "stages": stage_durations(stage_times),
        "stages_error": stages_error,
    }


def _stage_times(reader: Any, channels: list[dict[str, Any]]) -> tuple[list[dict], str | None]:
    """A live demo's ``/teleop/stage_times`` records (none in other demos: their chunks are not
    read), and why they could not be read (a damaged chunk: ``verify`` names it) or None."""
    from mcap.exceptions import McapError

    if not any(c["topic"] == STAGE_TIMES_TOPIC and c["messages"] for c in channels):
        return [], None
    try:
        msgs = reader.iter_messages(topics=[STAGE_TIMES_TOPIC])
        return [json.loads(m.data) for _, _, m in msgs], None
    except (McapError, ValueError) as e:
        return [], str(e)


#: The stages ``inspect`` reports from a live demo's stage times, each ``(name, later,
#: earlier)``: the difference of two times on one clock, ms.
STAGES = (
    ("page: capture -> sent", "sent_ms", "capture_ms"),
    ("server: received -> state sent", "state_sent_ms", "server_recv_ms"),
    ("round trip: sent -> state received", "page_recv_ms", "sent_ms"),
    ("hand age when its state arrived", "page_recv_ms", "capture_ms"),
)


def stage_durations(records: list[dict[str, Any]]) -> dict[str, dict[str, float]]:
    """``{stage: {n, p50, p99}}`` (ms) of each of :data:`STAGES` over the ``/teleop/stage_times``
    records where both its times are known, and ``network and page queue: round trip - server``
    (the wire and the wait in the page's event loop); empty for a demo without stage times."""
    out: dict[str, dict[str, float]] = {}

    def add(name: str, values: list[float]) -> None:
        if values:
            v = np.asarray(values)
            out[name] = {
                "n": len(v),
                "p50": float(np.percentile(v, 50)),
                "p99": float(np.percentile(v, 99)),
            }

    for name, later, earlier in STAGES:
        add(name, [r[later] - r[earlier] for r in records if r.get(later) is not None])
    rtt_minus_server = [
        (r["page_recv_ms"] - r["sent_ms"]) - (r["state_sent_ms"] - r["server_recv_ms"])
        for r in records
        if r.get("page_recv_ms") is not None and r.get("state_sent_ms") is not None
    ]
    add("network and page queue: round trip - server", rtt_minus_server)
    return out
