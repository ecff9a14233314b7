"""Gesture model files: loading what `mimicrete gesture train` saved (per-frame or temporal), and
the shipped models' paths."""

from __future__ import annotations

import hashlib
import io
import json
import warnings
from pathlib import Path
from typing import Any

from .classes import DEFAULT_KIND, MODELS_DIR, TASK_MODEL, GestureDataError
from .model import GestureModel, _versions
from .temporal import TemporalGestureModel


def load_model(path: str | Path) -> GestureModel:
    """Load a model written by :meth:`GestureModel.save` (a
    :class:`~mimicrete.gestures.temporal.TemporalGestureModel` when its kind is temporal); warns
    when the sklearn or numpy version differs from the one it was fitted with (pickled sklearn
    models may then misbehave). ``info["sha256"]`` is the SHA-256 of exactly the bytes loaded
    (hand logs name the model that read them by it)."""
    import joblib

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such gesture model file")
    side = Path(str(path) + ".json")
    info: dict[str, Any] = {}
    notes: list[str] = []  # version warnings, given once the file proves to be a model
    if side.exists():
        meta = json.loads(side.read_text())
        info = meta.get("info", {})
        now = _versions()
        for key in ("sklearn", "numpy"):
            then = meta.get("versions", {}).get(key)
            if then != now[key]:
                notes.append(
                    f"{path}: fitted with {key} {then}, running {now[key]}; retrain with "
                    f"`mimicrete gesture train` if predictions look wrong"
                )
    else:
        notes.append(f"{path}: no sidecar {side.name}; versions unknown")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sklearn's own InconsistentVersionWarning: ours is above
        try:
            data = path.read_bytes()
            d = joblib.load(io.BytesIO(data))
        except OSError:
            raise
        except Exception as e:  # joblib/pickle raise many types on foreign bytes
            raise GestureDataError(f"{path}: not a gesture model ({type(e).__name__})") from None
    keys = ("pipeline", "classes", "layout", "dims", "task")
    if not isinstance(d, dict) or any(k not in d for k in keys):
        raise GestureDataError(
            f"{path}: not a gesture model written by `mimicrete gesture train` "
            f"(expected a dict with {', '.join(keys)})"
        )
    for note in notes:
        warnings.warn(note, RuntimeWarning, stacklevel=2)
    # demos recorded with it name the file; hand logs name it by its hash too
    info = {**info, "path": str(path.resolve()), "sha256": hashlib.sha256(data).hexdigest()}
    args = (d["pipeline"], tuple(d["classes"]), d["layout"], d["dims"], d["task"], info)
    kind = d.get("kind", "per-frame")
    if kind == "temporal":
        return TemporalGestureModel(*args, window=int(d["window"]), parts=tuple(d["parts"]))
    if kind != "per-frame":
        raise GestureDataError(f"{path}: unknown gesture model kind {kind!r}")
    return GestureModel(*args)


def default_model_path(task: str, kind: str | None = None) -> Path:
    """Where the shipped model for ``task`` (``grip``/``suction``/``screw``) lives; ``kind``
    (``per-frame``/``temporal``) defaults to :data:`DEFAULT_KIND` of the task."""
    task = TASK_MODEL.get(task, task)
    kind = kind or DEFAULT_KIND.get(task, "per-frame")
    if kind not in ("per-frame", "temporal"):
        raise ValueError(f"model kind must be 'per-frame' or 'temporal', got {kind!r}")
    suffix = "_temporal" if kind == "temporal" else ""
    return MODELS_DIR / f"gesture_{task}{suffix}.joblib"


def load_default(task: str, kind: str | None = None) -> GestureModel:
    """The shipped model for a task (``suction`` and ``grip`` share the 3-class model), of
    ``kind`` (default :data:`DEFAULT_KIND`)."""
    path = default_model_path(task, kind)
    if not path.exists():
        flag = " --temporal" if path.stem.endswith("_temporal") else ""
        raise FileNotFoundError(
            f"{path} missing: run `mimicrete gesture train{flag} --task "
            f"{TASK_MODEL.get(task, task)}`"
        )
    return load_model(path)
