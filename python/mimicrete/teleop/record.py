"""Recording a session: the MCAP demo (through the Rust ``demo-log`` writer), its metadata, the
stage times of a live one and its raw hand log."""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import _native, demos
from mimicrete.gestures import GestureModel
from mimicrete.hands import log as handlog

from .session import CONTROL_DT, Counts, Session
from .stage_times import StageClock

#: The layout of the live page's hands: WebXR's 25 joints.
LAYOUT = "webxr"
#: The hand's space as the formats name it: WebXR's axes are OpenXR's (right-handed, +Y up), and
#: the hand-log format reads ``webxr`` as ``openxr`` and writes ``openxr`` (docs/formats.md §1)
SPACE = "openxr"


def robot_model_of(extra: dict[str, Any]) -> str:
    """The arm a demo's episode ran on: its task spec's ``robot.model`` (``extra.task_spec``, the
    spec as it was read), ``"ur3"`` for a built-in task."""
    import json

    spec = extra.get("task_spec")
    if not spec:
        return "ur3"
    return str(json.loads(spec).get("robot", {}).get("model", "ur3"))


def episode_meta(
    *,
    episode: int,
    task_sim: str,
    seed: int,
    source: str | None,
    model: GestureModel,
    layout: str,
    space: str,
    handedness: str,
    extra: dict[str, Any],
) -> dict[str, Any]:
    """The demo's ``episode_start`` metadata (docs/formats.md, "Metadata records"); ``source`` is
    the hand log it comes from, if it exists when the demo is opened."""
    gesture = f"svm-{model.task} ({'/'.join(model.classes)})"
    path = model.info.get("path")
    if path:
        extra = {**extra, "gesture_model_file": str(path)}
    acc = model.info.get("test_accuracy")
    if acc is not None:
        extra = {**extra, "gesture_model_accuracy": float(acc)}
    meta: dict[str, Any] = {
        "episode": int(episode),
        "task": task_sim,
        "seed": int(seed),
        "robot_model": robot_model_of(extra),
        "gesture_model": gesture,
        "control_dt": float(CONTROL_DT),
        "hand": {"layout": layout, "space": space, "handedness": handedness},
        "extra": extra,
    }
    if source is not None:  # hashed by the writer, so it must exist by now
        meta["source_handlog"] = str(source)
    return meta


def source_keys(
    handlog: str | os.PathLike[str], demo: str | os.PathLike[str], sha256: str | None = None
) -> dict[str, str]:
    """The demo's ``source_handlog`` and ``source_handlog_sha256`` (docs/formats.md §2), the one
    way live demos and ``mimicrete convert`` write them: the hand log's name relative to the
    demo's folder (``TASK_0003.handlog.jsonl`` beside it, ``../hands/take.jsonl``), never an
    absolute path, so a folder of demos and logs can move; and the SHA-256 of its bytes
    (``sha256`` when the caller hashed what it parsed, else the file as it is now)."""
    rel = os.path.relpath(os.path.abspath(handlog), os.path.dirname(os.path.abspath(demo)))
    if sha256 is None:
        with open(handlog, "rb") as f:
            sha256 = hashlib.file_digest(f, "sha256").hexdigest()
    text = os.fsencode(rel).decode("utf-8", "backslashreplace")  # as convert.path_text
    return {"source_handlog": text, "source_handlog_sha256": sha256}


class DemoSink:
    """One episode's MCAP demo: ``w`` is the Rust demo-log writer (``mimicrete.demos.DemoWriter``)
    the session (teleop-core, in Rust) writes every hand frame and step into; this opens it with
    the episode's metadata and finishes, abandons or discards it."""

    def __init__(
        self, path: str | os.PathLike[str], meta: dict[str, Any], task_file: str | None = None
    ) -> None:
        """``task_file``: the task spec file the episode runs in; the demo draws its scene (its
        object and pad) at ``meta["seed"]``'s start. None: the built-in task's."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        env = None
        if task_file is not None:
            env = _native.SimEnv.from_spec_file(task_file, 0)
            env.reset(int(meta["seed"]))
        self.w = demos.DemoWriter(str(path), meta, env=env)

    def close(
        self,
        success: bool,
        counts: Counts,
        extra: dict[str, Any] | None = None,
        source: dict[str, str] | None = None,
    ) -> None:
        """Finish the file: the summary is written and it is renamed into place. ``extra`` values
        are stored as JSON; ``source`` (:func:`source_keys`, for a hand log written while the
        demo was recorded) goes into the ``episode`` record as it is."""
        info = {k: json.dumps(v) for k, v in counts.as_dict().items()}
        for k, v in (extra or {}).items():
            info[k] = json.dumps(v)
        info.update(source or {})
        self.w.finish(success, info)

    def abandon(self) -> None:
        """Close without finishing: the file stays as ``.partial`` (valid and salvageable)."""
        self.w.abandon()

    def discard(self) -> None:
        """Close without finishing and delete the partial file."""
        self.abandon_quietly()
        Path(str(self.path) + ".partial").unlink(missing_ok=True)

    def abandon_quietly(self) -> None:
        """:meth:`abandon`, also when the writer is finished or closed already (on error paths)."""
        try:
            self.w.abandon()
        except Exception:  # already finished (renamed) or closed: nothing left to close
            pass


@dataclass
class Recording:
    """A live episode being recorded: its session, its demo, the stage times of its steps and the
    raw frames for its hand log."""

    index: int
    seed: int
    session: Session
    sink: DemoSink
    t: list[float] = field(default_factory=list)
    tracked: list[bool] = field(default_factory=list)
    joints: list[np.ndarray] = field(default_factory=list)
    read_by: dict[str, Any] = field(default_factory=dict)  # the hand log's extra (at the start)
    clutch: list[list[Any]] = field(default_factory=list)  # [frame index, engage | release]
    stages: StageClock = field(init=False)

    def __post_init__(self) -> None:
        self.stages = StageClock(self.sink.w)


def write_handlog(
    path: Path,
    rec: Recording,
    task: str,
    mapping: str,
    spec: tuple[str, dict[str, Any]] | None = None,
) -> None:
    """The recording's raw hand log (docs/formats.md §1): every frame the page sent, and in its
    header's ``extra`` what read the hand and how it drove the robot, and ``spec`` (the task
    spec file and the spec it ran in: ``task_file``, ``task_spec``, as synth-hands writes them,
    so ``convert`` replays it there)."""
    extra: dict[str, Any] = {**rec.read_by, "mapping": mapping, "clutch": rec.clutch}
    if spec is not None:
        extra.update(task_file=spec[0], task_spec=spec[1])
    header = {
        "format": "mimicrete.handlog",
        "version": 1,
        "layout": LAYOUT,
        "space": SPACE,
        "handedness": "right",
        "units": "m",
        "task": task,
        "episode_seed": rec.seed,
        "source": "mimicrete teleop (WebXR page)",
        "extra": extra,
    }
    handlog.write(
        path,
        header,
        np.asarray(rec.t, dtype=np.float64),
        np.asarray(rec.tracked, dtype=bool),
        np.asarray(rec.joints, dtype=np.float64).reshape(-1, 25, 3),
    )
