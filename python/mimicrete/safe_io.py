"""Files written whole or not at all, and locks that a dead owner does not keep.

Writing (every file a command writes goes through one of these):

- :func:`atomic_write` (bytes or text) and :func:`torch_save` (serialised in memory first): a
  hidden temporary file beside the target, written in full, ``fsync``-ed, then renamed over the
  target. A failure (a full disk, a file-size limit, Ctrl-C) removes the temporary file, so the
  target is either the old file or the new one, never a part of one.
- :func:`atomic_output`: the same for writers that want a path (matplotlib, the ONNX exporter).
- :func:`append_text`: a line appended whole, or the file cut back to its old size.

A failed write is a :class:`WriteError` (an ``OSError``) whose message names the file and says why
in words: the disk is full (and how much is free where), or the file-size limit was hit.

Locking: :class:`FileLock` takes ``flock`` on a lock file and writes its owner (pid, start time,
command) into it. The kernel drops the lock when its owner dies, however it dies (SIGKILL
included), so a lock file left behind by a killed process is taken over, never in the way. The
lock is re-entrant within a process (a command and the library function it calls may both take
it).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import io
import itertools
import json
import os
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from mimicrete._native import MimicreteError

__all__ = [
    "FileLock",
    "LockBusyError",
    "WriteError",
    "append_text",
    "atomic_output",
    "atomic_write",
    "torch_save",
    "write_error",
]

_counter = itertools.count()


class WriteError(MimicreteError, OSError):
    """A file that could not be written; the message names it and the reason."""

    def __init__(self, err: int | None, message: str) -> None:
        super().__init__(err, message)
        self.message = message

    def __str__(self) -> str:
        return self.message


def _free_bytes(directory: Path) -> str:
    try:
        free = shutil.disk_usage(directory).free
    except OSError:
        return "unknown"
    for unit in ("bytes", "KiB", "MiB", "GiB"):
        if free < 1024 or unit == "GiB":
            return f"{free:.0f} {unit}" if unit == "bytes" else f"{free:.1f} {unit}"
        free /= 1024
    return f"{free:.1f} GiB"  # pragma: no cover


def write_error(path: str | os.PathLike[str], e: OSError) -> WriteError:
    """``e`` (raised while writing ``path``) as a :class:`WriteError` that says what happened."""
    if isinstance(e, WriteError):
        return e
    p = Path(path)
    where = p.parent if str(p.parent) else Path(".")
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        why = (
            f"the disk is full (no space left on the file system holding {where}, "
            f"{_free_bytes(where)} free)"
        )
    elif e.errno == errno.EFBIG:
        why = "the file would exceed this process's file-size limit (ulimit -f)"
    else:
        why = e.strerror or str(e)
    return WriteError(e.errno, f"{p}: not written: {why}; no partial file was left")


def _tmp_path(path: Path) -> Path:
    return path.with_name(f".{path.name}.{os.getpid()}.{next(_counter)}.tmp")


def _fsync_dir(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _write_all(fd: int, data: bytes | memoryview) -> None:
    view = memoryview(data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def atomic_write(path: str | os.PathLike[str], data: bytes | str) -> None:
    """Write ``data`` (text is UTF-8) to ``path`` whole or not at all (see the module doc)."""
    path = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    with atomic_output(path) as tmp:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        try:
            _write_all(fd, raw)
        finally:
            os.close(fd)


@contextlib.contextmanager
def atomic_output(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A temporary path to write ``path`` through: renamed onto ``path`` when the block ends
    normally, removed when it raises. Writers that pick a format from the file name must be
    told the format (the temporary name ends in ``.tmp``)."""
    path = Path(path)
    tmp = _tmp_path(path)
    try:
        yield tmp
        fd = os.open(tmp, os.O_RDONLY | os.O_CLOEXEC)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(e, OSError):
            raise write_error(path, e) from e
        raise
    _fsync_dir(path.parent)


def torch_save(obj: Any, path: str | os.PathLike[str]) -> None:
    """``torch.save(obj, path)`` whole or not at all: serialised in memory, then
    :func:`atomic_write` (torch's own writer reports a full disk as "unexpected pos")."""
    import torch

    buf = io.BytesIO()
    torch.save(obj, buf)
    atomic_write(path, buf.getbuffer())


def append_text(path: str | os.PathLike[str], text: str) -> None:
    """Append ``text`` to ``path`` whole: on a failed write the file is cut back to the size it
    had, so no half line is left."""
    path = Path(path)
    raw = text.encode("utf-8")
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        size = os.fstat(fd).st_size
        try:
            _write_all(fd, raw)
        except BaseException as e:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, size)
            if isinstance(e, OSError):
                raise write_error(path, e) from e
            raise
    finally:
        os.close(fd)


# ----------------------------------------------------------------------------------------------
# locks
# ----------------------------------------------------------------------------------------------


class LockBusyError(MimicreteError, RuntimeError):
    """The lock is held by another live process (the message names it)."""


_held: dict[str, list[Any]] = {}  # real path of a lock file -> [fd, count] (this process)
_held_guard = threading.Lock()
_DEFERRED = (signal.SIGHUP, signal.SIGTERM, signal.SIGINT)  # put back in this order: Ctrl-C last


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """Ctrl-C, SIGTERM and SIGHUP held back for the block, not lost: a lock is taken or given
    up whole, never cut between its file and this process's table of held locks. A signal that
    comes meanwhile is noted; on leaving, the handlers are put back and it is raised again, so its
    exception (or its default action) happens there. Python runs signal handlers in the main
    thread only, so other threads run the block as it is. (Blocking the signal in the thread
    would not do: the kernel hands it to another thread, whose C handler still wakes Python's.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    before: dict[int, Any] = {}
    for sig in _DEFERRED:
        old = signal.getsignal(sig)
        if old is not None:  # None: a handler installed outside Python, left alone
            before[sig] = old
            signal.signal(sig, lambda signum, _frame: came.append(signum))
    try:
        yield
    finally:
        for sig, old in before.items():
            signal.signal(sig, old)
        for sig in dict.fromkeys(came):
            signal.raise_signal(sig)


def _owner_text(fd: int) -> str:
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        raw = os.read(fd, 4096).decode("utf-8", "replace")
        info = json.loads(raw)
        if not isinstance(info, dict):
            raise ValueError
    except (OSError, ValueError):
        return "another process"
    pid = info.get("pid")
    since = info.get("since")
    cmd = str(info.get("command", ""))[:120]
    when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(since)) if since else "?"
    return f"process {pid} ({cmd!s}, since {when})"


class FileLock:
    """An exclusive lock on ``path`` (a lock file, created if missing) held by this process.

    Taking it when a live process holds it raises ``error(message)`` at once (no waiting); the
    message names the lock file, ``what`` is locked and the owner. A lock file whose owner died
    is taken over. Leaving the ``with`` block removes the lock file."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        what: str,
        error: Callable[[str], BaseException] = LockBusyError,
    ) -> None:
        self.path = Path(path)
        self.what = what
        self.error = error
        self._key: str | None = None
        self._depth = 0  # acquisitions through this object not yet released

    def acquire(self) -> FileLock:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        depth = self._depth
        try:
            with _signals_deferred():
                self._acquire()
        except BaseException:
            if self._depth > depth:  # taken, then a signal delivered on the way out: give it up
                self.release()
            raise
        return self

    def _acquire(self) -> None:
        key = os.path.realpath(self.path)
        with _held_guard:
            if key in _held:
                _held[key][1] += 1
                self._key = key
                self._depth += 1
                return
            while True:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    owner = _owner_text(fd)
                    os.close(fd)
                    raise self.error(
                        f"{self.path}: {self.what} is in use by {owner}; wait for it to finish "
                        "(a lock of a process that died is taken over by itself)"
                    ) from None
                except BaseException:
                    os.close(fd)
                    raise
                # a releasing owner unlinks the file before unlocking: the file locked must
                # still be the one at the path, else take the new one
                try:
                    same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
                except FileNotFoundError:
                    same = False
                if same:
                    break
                os.close(fd)
            try:
                info = {
                    "pid": os.getpid(),
                    "since": time.time(),
                    "command": " ".join(os.path.basename(a) if i == 0 else a
                                        for i, a in enumerate(sys.argv))[:400],
                }  # fmt: skip
                os.ftruncate(fd, 0)
                _write_all(fd, json.dumps(info).encode())
            except BaseException:
                with contextlib.suppress(OSError):
                    self.path.unlink()
                os.close(fd)
                raise
            _held[key] = [fd, 1]
            self._key = key
            self._depth += 1

    def release(self) -> None:
        released = False
        try:
            with _signals_deferred():
                self._release()
                released = True
        except BaseException:
            # a signal that came as the deferral was being set up (before its handlers were in)
            # raised there, before the lock was given up: give it up now, then let it through
            if not released:
                self._release()
            raise

    def _release(self) -> None:
        key = self._key
        if key is None or self._depth == 0:
            return
        self._depth -= 1
        if self._depth == 0:
            self._key = None
        with _held_guard:
            entry = _held.get(key)
            if entry is None:
                return
            entry[1] -= 1
            if entry[1] > 0:
                return
            del _held[key]
            with contextlib.suppress(OSError):
                self.path.unlink()
            os.close(entry[0])

    def __enter__(self) -> FileLock:
        return self.acquire()

    def __exit__(self, *exc: object) -> None:
        self.release()
