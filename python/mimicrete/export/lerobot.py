"""Demos → a LeRobot dataset, format v3.0, written with pyarrow (lerobot itself is not needed).

Layout (what ``lerobot.datasets.lerobot_dataset.LeRobotDataset(repo_id, root=OUT)`` reads)::

    OUT/meta/info.json                            codebase_version "v3.0", fps, features, totals
    OUT/meta/stats.json                           per feature: min max mean std count q01...q99
    OUT/meta/tasks.parquet                        the task sentence (index) -> task_index
    OUT/meta/episodes/chunk-000/file-000.parquet  one row per episode (see below)
    OUT/data/chunk-000/file-000.parquet           one row per step (a new file every ~100 MB)

Frame features: ``observation.state`` (float32, the env's observation vector: 5 stacked frames,
oldest first), ``action`` (float32: the six joint motions the env received and the effector
command as a level, ``suction_level`` / ``gripper_level`` = +1 / -1 held until the next command,
not the demo's one-step switch; :mod:`mimicrete.export.levels`, docs/formats.md section 4; the
env takes it as it is), ``next.reward`` (float32),
``next.done`` (the episode ended after this step: true on each episode's last frame),
``next.terminated`` / ``next.truncated`` (gymnasium's flags of the step), ``next.success`` (the
task was achieved after this step: tile-sim's ``installed`` / placed / screwed flag, from the
replay), and LeRobot's own ``timestamp`` (= frame_index / fps), ``frame_index``,
``episode_index``, ``index``, ``task_index``. fps is the control rate (25 Hz).

Episode rows hold LeRobot's columns (``episode_index``, ``tasks``, ``length``, the data file and
row range, ``stats/<feature>/<stat>``) and ours: ``mimicrete/seed`` (the simulator seed, uint64),
``mimicrete/start`` (a generated demo's recorded start as JSON, ``object_pose``, ``target_offset``,
TilePlace's ``pad_yaw``, the reset options that start its episode with the seed; "" for a demo
started at its seed's own start),
``mimicrete/success``, ``mimicrete/total_reward``, ``mimicrete/source_demo`` (the MCAP's file
name), ``mimicrete/source_handlog`` and ``mimicrete/source_handlog_sha256`` (the hand log it came
from), ``mimicrete/terminated``.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete.export.source import (
    ACTION_NAMES,
    FRAME_NAMES,
    DemoSet,
    ExportError,
    check_new_output,
)

CODEBASE_VERSION = "v3.0"
CHUNKS_SIZE = 1000  # files per chunk directory
DATA_FILE_MB = 100  # a new data file once the current one holds this much (uncompressed)
VIDEO_FILE_MB = 200
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
EPISODES_PATH = "meta/episodes/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)
ROBOT_TYPE = "ur3"


def features(ds: DemoSet) -> dict[str, dict[str, Any]]:
    """The dataset's features as info.json lists them (dtype, shape, names)."""
    stack = ds.obs_dim // len(FRAME_NAMES[ds.task])
    obs_names = [
        f"t{k - stack + 1}.{n}" if k < stack - 1 else f"t.{n}"
        for k in range(stack)
        for n in FRAME_NAMES[ds.task]
    ]
    scalar = {"shape": [1], "names": None}
    return {
        "observation.state": {"dtype": "float32", "shape": [ds.obs_dim], "names": obs_names},
        "action": {"dtype": "float32", "shape": [ds.act_dim], "names": ACTION_NAMES[ds.task]},
        "next.reward": {"dtype": "float32", **scalar},
        "next.done": {"dtype": "bool", **scalar},
        "next.terminated": {"dtype": "bool", **scalar},
        "next.truncated": {"dtype": "bool", **scalar},
        "next.success": {"dtype": "bool", **scalar},
        "timestamp": {"dtype": "float32", **scalar},
        "frame_index": {"dtype": "int64", **scalar},
        "episode_index": {"dtype": "int64", **scalar},
        "index": {"dtype": "int64", **scalar},
        "task_index": {"dtype": "int64", **scalar},
    }


def _columns(ds: DemoSet, ep_index: int, start: int) -> dict[str, np.ndarray]:
    """One episode's frame columns as numpy arrays, keyed by feature."""
    ep = ds.episodes[ep_index]
    n = len(ep)
    done = np.zeros(n, dtype=bool)
    done[-1] = True
    frame = np.arange(n, dtype=np.int64)
    return {
        "observation.state": ep.obs,
        "action": ep.actions,
        "next.reward": ep.rewards.astype(np.float32),
        "next.done": done,
        "next.terminated": ep.terminated,
        "next.truncated": ep.truncated,
        "next.success": ep.info["installed"],
        "timestamp": (frame / ds.fps).astype(np.float32),
        "frame_index": frame,
        "episode_index": np.full(n, ep_index, dtype=np.int64),
        "index": np.arange(start, start + n, dtype=np.int64),
        "task_index": np.zeros(n, dtype=np.int64),
    }


def _arrow_table(cols: dict[str, np.ndarray], feats: dict[str, dict[str, Any]]) -> Any:
    import pyarrow as pa

    arrays, fields = [], []
    for key, ft in feats.items():
        v = cols[key]
        dtype = pa.from_numpy_dtype(np.dtype(ft["dtype"]))
        if ft["shape"] == [1]:
            arr = pa.array(v.reshape(-1), type=dtype)
        else:
            width = int(ft["shape"][0])
            flat = pa.array(np.ascontiguousarray(v, dtype=ft["dtype"]).reshape(-1), type=dtype)
            arr = pa.FixedSizeListArray.from_arrays(flat, width)
        arrays.append(arr)
        fields.append(pa.field(key, arr.type))
    return pa.Table.from_arrays(arrays, schema=pa.schema(fields))


def _stats(v: np.ndarray) -> dict[str, np.ndarray]:
    """LeRobot's per-feature statistics of a (n,) or (n, d) array (exact quantiles)."""
    x = v.astype(np.float64).reshape(len(v), -1)
    out = {
        "min": x.min(axis=0),
        "max": x.max(axis=0),
        "mean": x.mean(axis=0),
        "std": x.std(axis=0),
        "count": np.array([len(x)], dtype=np.int64),
    }
    qs = np.quantile(x, QUANTILES, axis=0)
    for q, row in zip(QUANTILES, qs, strict=True):
        out[f"q{round(q * 100):02d}"] = row
    return out


def _next_file(chunk: int, file: int) -> tuple[int, int]:
    return (chunk + 1, 0) if file == CHUNKS_SIZE - 1 else (chunk, file + 1)


def _tasks_table(task_text: str) -> Any:
    """meta/tasks.parquet: the task sentence as the pandas index, ``task_index`` its number (the
    ``pandas`` schema metadata is the documented one pandas writes, so pandas reads the index
    back without pandas being needed here)."""
    import pyarrow as pa

    pandas_meta = {
        "index_columns": ["task"],
        "column_indexes": [
            {
                "name": None,
                "field_name": None,
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": {"encoding": "UTF-8"},
            }
        ],
        "columns": [
            {
                "name": "task_index",
                "field_name": "task_index",
                "pandas_type": "int64",
                "numpy_type": "int64",
                "metadata": None,
            },
            {
                "name": "task",
                "field_name": "task",
                "pandas_type": "unicode",
                "numpy_type": "object",
                "metadata": None,
            },
        ],
        "creator": {"library": "mimicrete", "version": _version()},
        "pandas_version": "2.2.0",
    }
    schema = pa.schema(
        [pa.field("task_index", pa.int64()), pa.field("task", pa.string())],
        metadata={b"pandas": json.dumps(pandas_meta).encode()},
    )
    return pa.Table.from_arrays([pa.array([0], pa.int64()), pa.array([task_text])], schema=schema)


def _version() -> str:
    try:
        from importlib.metadata import version

        return version("mimicrete")
    except Exception:  # running from a source tree
        return "0+source"


def write(ds: DemoSet, out: str | os.PathLike[str]) -> Path:
    """Write ``ds`` as a LeRobot v3.0 dataset in the new directory ``out`` (built in a temporary
    directory beside it, then renamed: a failure leaves nothing at ``out``)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    out = check_new_output(out)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        _write(ds, tmp, pa, pq)
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _write(ds: DemoSet, root: Path, pa: Any, pq: Any) -> None:
    feats = features(ds)
    task_text = ds.instruction
    (root / "meta").mkdir(parents=True)
    pq.write_table(_tasks_table(task_text), root / "meta" / "tasks.parquet")

    chunk, file = 0, 0
    writer = None
    file_bytes = 0
    start = 0
    episode_rows: list[dict[str, Any]] = []
    all_cols: dict[str, list[np.ndarray]] = {k: [] for k in feats}
    try:
        for i, ep in enumerate(ds.episodes):
            cols = _columns(ds, i, start)
            table = _arrow_table(cols, feats)
            if writer is not None and file_bytes + table.nbytes > DATA_FILE_MB * 1024 * 1024:
                writer.close()
                writer = None
                chunk, file = _next_file(chunk, file)
            if writer is None:
                path = root / DATA_PATH.format(chunk_index=chunk, file_index=file)
                path.parent.mkdir(parents=True, exist_ok=True)
                writer = pq.ParquetWriter(path, table.schema, compression="snappy")
                file_bytes = 0
            writer.write_table(table)
            file_bytes += table.nbytes
            row: dict[str, Any] = {
                "episode_index": i,
                "tasks": [task_text],
                "length": len(ep),
                "data/chunk_index": chunk,
                "data/file_index": file,
                "dataset_from_index": start,
                "dataset_to_index": start + len(ep),
                "meta/episodes/chunk_index": 0,
                "meta/episodes/file_index": 0,
            }
            for key, v in cols.items():
                all_cols[key].append(v)
                for stat, value in _stats(v).items():
                    row[f"stats/{key}/{stat}"] = value.tolist()
            row.update(
                {
                    "mimicrete/seed": ep.seed,
                    "mimicrete/start": json.dumps(ep.start) if ep.start else "",
                    "mimicrete/success": ep.success,
                    "mimicrete/total_reward": float(ep.rewards.sum()),
                    "mimicrete/terminated": bool(ep.terminated[-1]),
                    "mimicrete/source_demo": Path(ep.file).name,
                    "mimicrete/source_handlog": ep.meta.get("source_handlog", ""),
                    "mimicrete/source_handlog_sha256": ep.meta.get("source_handlog_sha256", ""),
                }
            )
            episode_rows.append(row)
            start += len(ep)
    finally:
        if writer is not None:
            writer.close()

    _write_episodes(episode_rows, root, pa, pq)
    stats = {
        key: {s: v.tolist() for s, v in _stats(np.concatenate(parts)).items()}
        for key, parts in all_cols.items()
    }
    (root / "meta" / "stats.json").write_text(json.dumps(stats, indent=4))
    n_ep = len(ds.episodes)
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": ROBOT_TYPE,
        "total_episodes": n_ep,
        "total_frames": start,
        "total_tasks": 1,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": DATA_FILE_MB,
        "video_files_size_in_mb": VIDEO_FILE_MB,
        "fps": ds.fps,
        "splits": {"train": f"0:{n_ep}"},
        "data_path": DATA_PATH,
        "video_path": None,
        "features": feats,
    }
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=4))


def _write_episodes(rows: list[dict[str, Any]], root: Path, pa: Any, pq: Any) -> None:
    if not rows:
        raise ExportError("no episodes to write")
    types = {"tasks": pa.list_(pa.string()), "mimicrete/seed": pa.uint64()}
    columns = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        if key in types:
            columns[key] = pa.array(values, type=types[key])
        elif key.endswith("/count"):
            columns[key] = pa.array(values, type=pa.list_(pa.int64()))
        elif key.startswith("stats/"):
            columns[key] = pa.array(values, type=pa.list_(pa.float64()))
        else:
            columns[key] = pa.array(values)
    path = root / EPISODES_PATH.format(chunk_index=0, file_index=0)
    path.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(columns), path, compression="snappy")
