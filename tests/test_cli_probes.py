"""Issue 24, items 11 and 15, through the real command line: one ``convert`` into an ``--out`` at a
time (a dead one's lock taken over), a closed stdout that does not stop the work, Ctrl-C at any
moment without a traceback, and the README's own ``export`` command with a relative ``--out``."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from mimicrete import cli

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _cli_run import run_cli  # noqa: E402

PACKAGE_ROOT = str(Path(cli.__file__).parents[2])
LOGS = 3


def cli_env(**more: str) -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": PACKAGE_ROOT, **more}


@pytest.fixture(scope="module")
def hand_logs(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hands")
    r = run_cli("synth-hands", "--task", "suction", "--episodes", str(LOGS), "--out", str(d))
    assert r.returncode == 0, r.stderr
    assert len(list(d.glob("*.jsonl"))) == LOGS
    return d


@pytest.fixture(scope="module")
def one_log(hand_logs, tmp_path_factory) -> Path:
    """A directory holding the first hand log only."""
    d = tmp_path_factory.mktemp("one")
    first = sorted(hand_logs.glob("*.jsonl"))[0]
    (d / first.name).write_bytes(first.read_bytes())
    return d


@pytest.fixture(scope="module")
def demo_dir(one_log, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("demos") / "suction"
    r = run_cli("convert", str(one_log), "--task", "suction", "--out", str(out), "--no-progress")
    assert r.returncode == 0, r.stderr
    return out


HOLD = textwrap.dedent(
    """
    import sys
    from mimicrete.safe_io import FileLock
    FileLock(sys.argv[1], "test").acquire()
    print("held", flush=True)
    sys.stdin.read()
    """
)


def hold_lock(path: Path) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-c", HOLD, str(path)], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True, env=cli_env())  # fmt: skip
    assert p.stdout is not None and p.stdout.readline().strip() == "held"
    return p


# ----------------------------------------------------------------------------------------------
# 11. convert: one process per --out; a killed owner's lock is taken over
# ----------------------------------------------------------------------------------------------


def test_a_second_convert_into_a_running_converts_out_is_refused(hand_logs, tmp_path, capsys):
    out = tmp_path / "demos"
    first = subprocess.Popen(
        [sys.executable, "-m", "mimicrete", "convert", str(hand_logs), "--task", "suction",
         "--out", str(out), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=cli_env(),
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not (out / ".lock").exists() and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    capsys.readouterr()
    rc = cli.main(["convert", str(hand_logs), "--task", "suction", "--out", str(out),
                   "--no-progress"])  # fmt: skip
    err = capsys.readouterr().err
    _, first_err = first.communicate(timeout=300)
    assert first.returncode == 0, first_err
    assert rc == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mimicrete convert: error: "), err
    assert ".lock" in lines[0] and f"in use by process {first.pid}" in lines[0]
    assert len(list(out.glob("*.mcap"))) == LOGS
    assert not (out / ".lock").exists()


def test_a_lock_left_by_a_killed_convert_is_taken_over(one_log, tmp_path):
    out = tmp_path / "demos"
    out.mkdir()
    holder = hold_lock(out / ".lock")
    try:
        r = run_cli("convert", str(one_log), "--task", "suction", "--out", str(out),
                    "--no-progress")  # fmt: skip
        assert r.returncode == 2
        assert f"process {holder.pid}" in r.stderr and "Traceback" not in r.stderr
        assert sorted(p.name for p in out.iterdir()) == [".lock"]
    finally:
        holder.send_signal(signal.SIGKILL)
        holder.wait()
    assert (out / ".lock").exists()  # the killed owner could not remove it
    r = run_cli("convert", str(one_log), "--task", "suction", "--out", str(out), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert len(list(out.glob("*.mcap"))) == 1 and not (out / ".lock").exists()


def test_a_refused_convert_leaves_no_empty_out(one_log, tmp_path):
    (tmp_path / "a.jsonl").write_bytes(next(one_log.glob("*.jsonl")).read_bytes())
    (tmp_path / "a.handlog.jsonl").write_text((tmp_path / "a.jsonl").read_text())
    out = tmp_path / "new" / "demos"
    r = run_cli("convert", str(tmp_path), "--task", "suction", "--out", str(out), "--no-progress")
    assert r.returncode == 2 and "both be written as a.mcap" in r.stderr
    assert not out.exists()


def test_the_lock_is_reentrant_in_a_process_and_exclusive_between_processes(tmp_path):
    from mimicrete.safe_io import FileLock, LockBusyError

    path = tmp_path / "x.lock"
    with FileLock(path, "x"), FileLock(path, "x"):
        assert path.exists()
        r = subprocess.run(
            [sys.executable, "-c", "import sys; from mimicrete.safe_io import FileLock; "
             "FileLock(sys.argv[1], 'the thing').acquire()", str(path)],
            capture_output=True, text=True, env=cli_env(),
        )  # fmt: skip
        assert r.returncode == 1 and "LockBusyError" in r.stderr and "the thing" in r.stderr
        assert f"process {os.getpid()}" in r.stderr
    assert not path.exists()
    same = FileLock(path, "x")
    same.acquire()
    same.acquire()
    same.release()
    assert path.exists()  # still held once
    same.release()
    assert not path.exists()
    with pytest.raises(LockBusyError):
        holder = hold_lock(path)
        try:
            FileLock(path, "x").acquire()
        finally:
            holder.kill()
            holder.wait()



class _InterruptingDict(dict):
    """The table of held locks, with a Ctrl-C to this process right after an entry goes in."""

    def __setitem__(self, key, value):
        super().__setitem__(key, value)
        os.kill(os.getpid(), signal.SIGINT)


class _InterruptingGuard:
    """The lock table's guard, with a Ctrl-C to this process as it is entered."""

    def __init__(self):
        import threading

        self.inner = threading.Lock()

    def __enter__(self):
        os.kill(os.getpid(), signal.SIGINT)
        return self.inner.__enter__()

    def __exit__(self, *exc):
        return self.inner.__exit__(*exc)


@pytest.fixture()
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt in this process for the test, as at a terminal (a run from
    a shell's background job or nohup starts with SIGINT ignored)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


def test_ctrl_c_while_a_lock_is_taken_leaves_no_lock_file(tmp_path, monkeypatch, ctrl_c_raises):
    """CI caught ``convert``'s Ctrl-C leaving ``demo.mcap.lock`` behind: the signal came while the
    lock was being taken or given up. It is held back until the lock's state is whole again."""
    from mimicrete import safe_io

    path = tmp_path / "taken.lock"
    monkeypatch.setattr(safe_io, "_held", _InterruptingDict())
    with pytest.raises(KeyboardInterrupt):  # taken, then given up again on the way out
        with safe_io.FileLock(path, "x"):
            pytest.fail("the block ran although Ctrl-C came while the lock was taken")
    assert not path.exists() and not safe_io._held
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_while_a_lock_is_given_up_leaves_no_lock_file(tmp_path, monkeypatch, ctrl_c_raises):
    from mimicrete import safe_io

    path = tmp_path / "released.lock"
    lock = safe_io.FileLock(path, "x").acquire()
    monkeypatch.setattr(safe_io, "_held_guard", _InterruptingGuard())
    with pytest.raises(KeyboardInterrupt):
        lock.release()
    assert not path.exists() and not safe_io._held
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler

def test_ctrl_c_as_the_release_starts_leaves_no_lock_file(tmp_path, monkeypatch, ctrl_c_raises):
    """CI caught it again: Ctrl-C landing as ``release`` was setting up its deferral of signals
    (before the handlers were in) raised there, and the lock file stayed."""
    from mimicrete import safe_io

    path = tmp_path / "released.lock"
    lock = safe_io.FileLock(path, "x").acquire()
    real = signal.getsignal
    sent = []

    def getsignal_then_ctrl_c(sig):
        if not sent:
            sent.append(sig)
            os.kill(os.getpid(), signal.SIGINT)
        return real(sig)

    monkeypatch.setattr(safe_io.signal, "getsignal", getsignal_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        lock.release()
    monkeypatch.setattr(safe_io.signal, "getsignal", real)
    assert sent and not path.exists() and not safe_io._held
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


# ----------------------------------------------------------------------------------------------
# 15. a closed stdout, Ctrl-C, a relative --out
# ----------------------------------------------------------------------------------------------


def test_convert_piped_into_head_converts_every_log(hand_logs, tmp_path):
    out = tmp_path / "demos"
    cmd = (f"set -o pipefail; {sys.executable} -m mimicrete convert {hand_logs} --task suction "
           f"--out {out} --no-progress | head -1")  # fmt: skip
    r = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, timeout=300,
                       env=cli_env(PYTHONUNBUFFERED="1"))  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert len(r.stdout.splitlines()) == 1
    assert "Traceback" not in r.stderr and "BrokenPipe" not in r.stderr
    assert len(list(out.glob("*.mcap"))) == LOGS


def test_inspect_piped_into_head_is_quiet(demo_dir):
    demo = sorted(demo_dir.glob("*.mcap"))[0]
    cmd = f"set -o pipefail; {sys.executable} -m mimicrete inspect {demo} | head -1"
    r = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, timeout=120,
                       env=cli_env())  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert len(r.stdout.splitlines()) == 1 and r.stderr == ""


TRAIN_PY = str(Path(cli.__file__).parents[3] / "train.py")


@pytest.mark.parametrize(
    ("how", "delay"),
    [*[("-m", d) for d in (0.2, 0.35, 0.5, 0.7, 0.9, 1.2)],
     *[("train.py", d) for d in (0.25, 0.5, 0.8)]],
)  # fmt: skip
def test_ctrl_c_during_train_help_never_prints_a_traceback(how, delay):
    cmd = ["-m", "mimicrete", "train"] if how == "-m" else [TRAIN_PY]
    p = subprocess.Popen([sys.executable, *cmd, "--help"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=cli_env())  # fmt: skip
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    if p.returncode == 0:  # it had finished
        assert "--resume" in out
    elif p.returncode == -signal.SIGINT:  # in the interpreter's own exit (handlers reset)
        assert err == ""
    else:
        assert p.returncode == 130 and err.strip().endswith("interrupted"), (p.returncode, err)


def test_ctrl_c_while_the_parser_is_built_is_exit_130(monkeypatch, capsys):
    def interrupted():
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["train", "--help"]) == 130
    assert capsys.readouterr().err.strip() == "mimicrete (starting): interrupted"


@pytest.mark.parametrize("relative", [True, False], ids=["relative-out", "absolute-out"])
def test_the_readme_minari_export_with_a_relative_or_absolute_out(demo_dir, tmp_path, relative):
    out = "exports/minari" if relative else str(tmp_path / "exports" / "minari")
    r = run_cli("export", str(demo_dir), "--format", "minari", "--out", out, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    root = tmp_path / "exports" / "minari"
    assert (root / "mimicrete" / "TileSuction" / "demos-v0" / "data" / "metadata.json").is_file()
    assert not [p for p in (tmp_path / "exports").iterdir() if p.name != "minari"]
