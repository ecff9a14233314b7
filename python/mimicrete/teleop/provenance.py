"""What read a hand log: the gesture model a live hand log's header names (``extra.gesture_model``:
its file, SHA-256 and classes; docs/formats.md §1), written by the live server
(:meth:`.live.Live._write_handlog`) and found again, checked and loaded by ``mimicrete convert``
(:func:`model_of`), so that converting a live hand log reads the hand with the model that read it
live and gives the live demo back step for step.

``file`` is relative to the hand log's folder (``gesture_suction_user.joblib`` beside it), so a
folder of demos, hand logs and the user's model can move; a shipped model (one in
:data:`mimicrete.gestures.MODELS_DIR`) is named by its file name there (``shipped: true``).
"""

from __future__ import annotations

import hashlib
import os
import re
from pathlib import Path
from typing import Any

from mimicrete import _native
from mimicrete import gestures as gest
from mimicrete._native import LogFormatError, MimicreteError

#: The header's ``extra`` key naming the gesture model.
KEY = "gesture_model"

_HEX64 = re.compile(r"[0-9a-f]{64}")
#: loaded models by (resolved file, SHA-256): a directory of hand logs read by one model loads it
#: once
_CACHE: dict[tuple[str, str], gest.GestureModel] = {}
_CACHE_MAX = 16


class ModelFileError(MimicreteError, ValueError):
    """The gesture model a hand log names cannot be used: missing, changed since the log was
    written (another SHA-256), not a model, or with other classes. The message names the hand
    log, the model file and the reason."""


def file_sha256(path: str | os.PathLike[str]) -> str:
    """Lower-case hex SHA-256 of a file's bytes."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def model_entry(model: gest.GestureModel, origin: str, handlog: str | os.PathLike[str]) -> dict:
    """The header's ``extra.gesture_model`` for a hand log written to ``handlog`` and read by
    ``model`` (``origin``: how the server picked it, ``given`` / ``user`` / ``shipped``).

    ``sha256`` is ``model.info["sha256"]`` (the bytes :func:`mimicrete.gestures.load_model`
    loaded, or the gesture mode saved), else the file's as it is now; ``file`` and ``sha256`` are
    None for a model that is no file (built in memory)."""
    entry: dict[str, Any] = {
        "file": None,
        "shipped": False,
        "sha256": None,
        "classes": list(model.classes),
        "kind": model.kind,
        "origin": origin,
    }
    path = model.info.get("path")
    if path:
        p = Path(path).resolve()
        if p.parent == gest.MODELS_DIR:
            entry["file"], entry["shipped"] = p.name, True
        else:
            try:
                rel = os.path.relpath(p, Path(handlog).resolve().parent)
            except ValueError:  # another drive (Windows): no relative path exists
                rel = str(p)
            entry["file"] = rel
        sha = model.info.get("sha256")
        entry["sha256"] = sha if sha else (file_sha256(p) if p.is_file() else None)
    return entry


def what_read(
    model: gest.GestureModel, origin: str, calibration: Any, handlog: str | os.PathLike[str]
) -> dict[str, Any]:
    """A live hand log's header ``extra``: what reads the hand, taken when the episode starts
    (the server's model or calibration may change before the log is written: a training that
    ends, a recentre after the stop): ``calibration`` (``Calibration.to_dict``) and
    ``gesture_model`` (:func:`model_entry`, ``file`` relative to ``handlog``'s folder)."""
    return {"calibration": calibration.to_dict(), KEY: model_entry(model, origin, handlog)}


def model_file(entry: dict, handlog: str | os.PathLike[str]) -> Path | None:
    """Where ``entry`` (an ``extra.gesture_model``) says the model is: beside the hand log
    ``handlog`` (its folder joined with ``file``), or in the shipped models' folder."""
    file = entry.get("file")
    if file is None:
        return None
    if entry.get("shipped"):
        return gest.MODELS_DIR / str(file)
    return Path(os.fspath(handlog)).parent / str(file)


def model_of(
    header: dict[str, Any], handlog: str | os.PathLike[str], source: str | None = None
) -> gest.GestureModel | None:
    """The gesture model a hand log's ``header`` names (None: it names none, an older or an
    offline log), loaded from :func:`model_file` after its SHA-256 was checked against the one
    the log gives. ``handlog`` is the log's path (the model's file is relative to its folder);
    ``source`` names it in messages (default ``handlog``).

    Raises:
        ModelFileError: the entry is malformed, or the model is not a file, is missing, has
            another SHA-256 (changed since the log was written), is not a model, or has other
            classes than the log says.
    """
    src = source if source is not None else os.fspath(handlog)
    extra = header.get("extra")
    entry = extra.get(KEY) if isinstance(extra, dict) else None
    if entry is None:
        return None
    where = f"extra.{KEY}"
    how = "; pass --gesture-model PATH to read the hand with a model of your choice"
    if not isinstance(entry, dict):
        raise ModelFileError(f"{src}: {where} must be an object (file, sha256, classes)")
    file, sha, classes = entry.get("file"), entry.get("sha256"), entry.get("classes")
    if file is not None and (not isinstance(file, str) or not file):
        raise ModelFileError(f"{src}: {where}.file must be a file name or null, got {file!r}")
    if file is None:
        raise ModelFileError(
            f"{src}: the gesture model that read this hand log was no file ({where}.file is "
            f"null){how}"
        )
    if not isinstance(sha, str) or not _HEX64.fullmatch(sha):
        raise ModelFileError(
            f"{src}: {where}.sha256 must be 64 lower-case hex digits, got {str(sha)[:80]!r}"
        )
    if not (isinstance(classes, list) and classes and all(isinstance(c, str) for c in classes)):
        raise ModelFileError(f"{src}: {where}.classes must be a list of class names")
    path = model_file(entry, handlog)
    assert path is not None
    shown = f"{where}.file {file!r}, " + (
        "a shipped model" if entry.get("shipped") else "relative to the hand log's folder"
    )
    if not path.is_file():
        raise ModelFileError(
            f"{src}: its gesture model {path} is missing ({shown}); put the file back{how}"
        )
    try:
        got = file_sha256(path)
    except OSError as e:
        raise ModelFileError(f"{src}: its gesture model {path}: {e.strerror or e}") from None
    changed = (
        f"{src}: its gesture model {path} is not the one that read it: SHA-256 {{got}}, the hand "
        f"log says {sha} (the file was replaced, e.g. by a new training){how}"
    )
    if got != sha:  # checked before the file is unpickled
        raise ModelFileError(changed.format(got=got))
    key = (str(path.resolve()), sha)
    model = _CACHE.get(key)
    if model is None:
        try:
            model = gest.load_model(path)
        except (OSError, ValueError, KeyError, EOFError) as e:
            raise ModelFileError(f"{src}: its gesture model {path}: {e}") from None
        if model.info.get("sha256") != sha:  # replaced between the check and the load
            raise ModelFileError(changed.format(got=model.info.get("sha256")))
        if len(_CACHE) >= _CACHE_MAX:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = model
    if list(model.classes) != classes:
        raise ModelFileError(
            f"{src}: its gesture model {path} has classes {list(model.classes)}, the hand log "
            f"says {classes}{how}"
        )
    return model


class DrivingError(LogFormatError, ValueError):
    """A hand log's ``extra.mapping`` or ``extra.clutch`` is malformed: a ``LogFormatError``
    (bad input, like any malformed hand log) naming the log, its header line and the field."""


def _driving_error(source: str, reason: str) -> DrivingError:
    """A :class:`DrivingError` about the header (line 1) of hand log ``source``, with the message
    and the ``file``, ``line``, ``reason`` fields of ``mimicrete.LogFormatError``."""
    like = _native.log_format_error(source, 1, reason)
    e = DrivingError(str(like))
    e.file, e.line, e.reason = like.file, like.line, like.reason
    return e


#: The mappings a hand log may name (teleop-core's ``Mapping``).
MAPPINGS = ("absolute", "clutch")


def driving_of(header: dict[str, Any], frames: int, source: str) -> tuple[str, dict[int, str]]:
    """How a hand log's hand drove the tool: ``extra.mapping`` (``absolute``, the default for a
    log that names none, or ``clutch``) and ``extra.clutch``'s commands by frame index (``[k,
    "engage" | "release"]``: applied with frame ``k``). Raises :class:`DrivingError` (a
    ``mimicrete.LogFormatError``) naming the log and the field for anything else."""
    extra = header.get("extra")
    extra = extra if isinstance(extra, dict) else {}
    mapping = extra.get("mapping", "absolute")
    if mapping not in MAPPINGS:
        raise _driving_error(
            source, f"extra.mapping must be one of {', '.join(MAPPINGS)}, got {mapping!r}"
        )
    events: dict[int, str] = {}
    raw = extra.get("clutch", [])
    if not isinstance(raw, list):
        raise _driving_error(source, f"extra.clutch must be a list, got {type(raw).__name__}")
    for i, e in enumerate(raw):
        ok = (
            isinstance(e, list)
            and len(e) == 2
            and isinstance(e[0], int)
            and not isinstance(e[0], bool)
            and 0 <= e[0] < frames
            and e[1] in ("engage", "release")
        )
        if not ok:
            raise _driving_error(
                source,
                f"extra.clutch[{i}] must be [frame index 0..{frames - 1}, "
                f"'engage' | 'release'], got {e!r}",
            )
        events[e[0]] = e[1]
    if events and mapping != "clutch":
        raise _driving_error(source, f"extra.clutch is given but extra.mapping is {mapping!r}")
    return mapping, events
