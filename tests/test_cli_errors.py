"""Every user-facing error path of the hand → demo commands, through the real CLI (a subprocess
running ``python -m mimicrete``): one line ``mimicrete <cmd>: error: …`` naming the file or flag,
exit 2 for bad input and 1 for a failed log, never a traceback, and nothing lost or silently
overwritten."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from _cli_run import run_cli as run
from mimicrete import demonstrator as sy
from mimicrete import demos


def no_traceback(p: subprocess.CompletedProcess[str]) -> None:
    assert "Traceback" not in p.stderr, p.stderr


@pytest.fixture(scope="module")
def hands(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hands")
    sy.synth_hands("suction", 2, 0, d)
    return d


def _with_header(src: Path, dst: Path, edit) -> Path:
    lines = src.read_text().splitlines()
    head = json.loads(lines[0])
    edit(head)
    lines[0] = json.dumps(head)
    dst.write_text("\n".join(lines) + "\n")
    return dst


def first_log(hands: Path) -> Path:
    return sorted(hands.glob("*.jsonl"))[0]


@pytest.mark.parametrize(
    ("args", "code", "message"),
    [
        (["convert", "missing_dir", "--task", "suction", "--out", "o"], 2, "missing_dir"),
        (["synth-hands", "--episodes", "0", "--out", "o"], 2, "--episodes must be >= 1"),
        (["teleop", "--out", "o", "--port", "0"], 2, "--port must be in 1..65535"),
    ],
)
def test_simple_user_errors(tmp_path, args, code, message):
    p = run(*args, cwd=tmp_path)
    no_traceback(p)
    assert p.returncode == code, p.stderr
    assert p.stderr.startswith(f"mimicrete {args[0]}: error: ") and message in p.stderr


def test_convert_out_is_a_file_and_bad_gesture_models(tmp_path, hands):
    (tmp_path / "afile").write_text("")
    p = run("convert", str(hands), "--task", "suction", "--out", str(tmp_path / "afile"))
    no_traceback(p)
    assert p.returncode == 2 and "exists and is not a directory" in p.stderr
    for model, says in [("nothere.joblib", "no such gesture model file"), ("bad", "not a")]:
        path = tmp_path / model
        if model == "bad":
            path.write_bytes(b"\x00not a pickle")
        p = run(
            "convert", str(hands), "--task", "suction", "--out", str(tmp_path / "o"),
            "--gesture-model", str(path),
        )  # fmt: skip
        no_traceback(p)
        assert p.returncode == 2 and "--gesture-model" in p.stderr and says in p.stderr
    assert not (tmp_path / "o").exists() or not list((tmp_path / "o").iterdir())


def test_convert_never_overwrites_without_asking(tmp_path, hands):
    out = tmp_path / "demos"
    assert run("convert", str(hands), "--task", "suction", "--out", str(out)).returncode == 0
    before = {p.name: p.stat().st_mtime_ns for p in out.glob("*.mcap")}
    p = run("convert", str(hands), "--task", "suction", "--out", str(out))
    no_traceback(p)
    assert p.returncode == 2 and "exist already" in p.stderr and "--overwrite" in p.stderr
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.mcap")} == before
    p = run("convert", str(hands), "--task", "suction", "--out", str(out), "--overwrite")
    assert p.returncode == 0 and demos.load(out).num_episodes == 2


def test_convert_names_are_unique_and_collisions_are_errors(tmp_path, hands):
    src = tmp_path / "src"
    src.mkdir()
    log = first_log(hands)
    (src / "take.v1.jsonl").write_bytes(log.read_bytes())
    (src / "take.v2.jsonl").write_bytes(log.read_bytes())
    p = run("convert", str(src), "--task", "suction", "--out", str(tmp_path / "o"))
    assert p.returncode == 0, p.stderr
    assert sorted(x.name for x in (tmp_path / "o").iterdir()) == ["take.v1.mcap", "take.v2.mcap"]
    (src / "take.v1.handlog.jsonl").write_bytes(log.read_bytes())  # also becomes take.v1.mcap
    p = run("convert", str(src), "--task", "suction", "--out", str(tmp_path / "o2"))
    no_traceback(p)
    assert p.returncode == 2 and "would both be written as take.v1.mcap" in p.stderr


@pytest.mark.parametrize(
    ("edit", "says"),
    [
        (lambda h: h["extra"].update(calibration="bogus"), "extra.calibration: must be an object"),
        (lambda h: h["extra"]["calibration"].update(scale=0), "scale must be > 0"),
        (
            lambda h: h["extra"]["calibration"].update(rotation=[[2, 0, 0], [0, 1, 0], [0, 0, 1]]),
            "not a rotation matrix",
        ),
    ],
)
def test_bad_calibration_is_named_not_defaulted(tmp_path, hands, edit, says):
    bad = _with_header(first_log(hands), tmp_path / "bad.jsonl", edit)
    p = run("convert", str(bad), "--task", "suction", "--out", str(tmp_path / "o"))
    no_traceback(p)
    assert p.returncode == 2 and f"{bad}:1: extra.calibration" in p.stderr and says in p.stderr
    assert "0 demos" in p.stdout and not list((tmp_path / "o").glob("*.mcap*"))


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        ({"mapping": "clutch", "clutch": [[0, "grab"]]}, "extra.clutch[0] must be [frame index"),
        ({"mapping": "clutch", "clutch": {"0": "engage"}}, "extra.clutch must be a list, got dict"),
        ({"clutch": [[0, "engage"]]}, "extra.clutch is given but extra.mapping is 'absolute'"),
        ({"mapping": "teleport"}, "extra.mapping must be one of absolute, clutch"),
    ],
)
def test_a_malformed_clutch_is_bad_input_naming_the_field(tmp_path, hands, extra, says):
    bad = _with_header(first_log(hands), tmp_path / "bad.jsonl", lambda h: h["extra"].update(extra))
    p = run("convert", str(bad), "--task", "suction", "--out", str(tmp_path / "o"))
    no_traceback(p)
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert f"mimicrete convert: error: {bad}:1: {says}" in p.stderr, p.stderr
    assert "0 demos" in p.stdout and not list((tmp_path / "o").glob("*.mcap*"))


def test_a_log_the_robot_never_followed_is_a_failure(tmp_path, hands):
    lines = first_log(hands).read_text().splitlines()
    frames = [json.loads(x) for x in lines[1:]]
    for f in frames:
        f["tracked"] = False
    dead = tmp_path / "dead.jsonl"
    dead.write_text("\n".join([lines[0], *map(json.dumps, frames)]) + "\n")
    p = run("convert", str(dead), "--task", "suction", "--out", str(tmp_path / "o"))
    no_traceback(p)
    assert p.returncode == 2 and "the robot never followed the hand" in p.stderr
    assert "untracked" in p.stderr and not list((tmp_path / "o").glob("*.mcap*"))


def test_lenient_skips_bad_lines_and_says_so(tmp_path, hands):
    lines = first_log(hands).read_text().splitlines()
    lines.insert(50, '{"t": "oops"}')
    log = tmp_path / "holey.jsonl"
    log.write_text("\n".join(lines) + "\n")
    strict = run("convert", str(log), "--task", "suction", "--out", str(tmp_path / "a"))
    assert strict.returncode == 2 and f"{log}:51:" in strict.stderr
    lenient = run(
        "convert", str(log), "--task", "suction", "--out", str(tmp_path / "b"), "--lenient"
    )
    assert lenient.returncode == 0, lenient.stderr
    assert "1 bad lines skipped" in lenient.stdout


def test_concurrent_converts_into_one_folder_never_corrupt(tmp_path, hands):
    out = tmp_path / "o"
    cmd = [sys.executable, "-m", "mimicrete", "convert", str(hands), "--task", "suction"]
    procs = [
        subprocess.Popen(
            [*cmd, "--out", str(out), "--overwrite", "--no-progress"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(2)
    ]
    results = [(p.wait(300), p.stderr.read()) for p in procs]
    for rc, err in results:
        no_traceback(subprocess.CompletedProcess([], rc, "", err))
        assert rc == 0 or "is in use by" in err, err  # the --out lock (owner maybe not written yet)
    d = demos.load(out)  # every demo there is complete and loads
    assert d.num_episodes == 2
    assert not list(out.glob("*.lock")) and not list(out.glob("*.partial"))


def test_gesture_train_errors_and_never_writes_into_the_package(tmp_path):
    import mimicrete.gestures as g

    csv = tmp_path / "one.csv"
    csv.write_text("".join("closing," + ",".join(["0.01"] * 63) + "\n" for _ in range(20)))
    p = run("gesture", "train", "--data", str(csv), "--out", str(tmp_path / "m.joblib"))
    no_traceback(p)
    assert p.returncode == 2 and "need at least 2 gesture classes" in p.stderr
    shipped = {q: q.stat().st_mtime_ns for q in g.MODELS_DIR.iterdir()}
    p = run("gesture", "train", "--task", "grip", "--quick", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "gesture_grip.joblib").exists()
    assert {q: q.stat().st_mtime_ns for q in g.MODELS_DIR.iterdir()} == shipped


def test_inspect_into_a_closed_pipe_is_quiet(tmp_path, hands):
    out = tmp_path / "o"
    assert run("convert", str(hands), "--task", "suction", "--out", str(out)).returncode == 0
    demo = sorted(out.glob("*.mcap"))[0]
    p = subprocess.run(
        f"{sys.executable} -m mimicrete inspect {demo} | head -1",
        shell=True,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "Traceback" not in p.stderr and "BrokenPipe" not in p.stderr
    assert demo.name in p.stdout


def test_ctrl_c_in_convert_exits_130_and_leaves_no_broken_file(tmp_path):
    """SIGINT mid-run: exit 130 with one line, the demos already written intact, the one being
    written removed with its lock (no .partial, no .lock)."""
    import signal
    import time

    hands = tmp_path / "hands"
    n = 40  # enough that the run is far from done when the first demo lands, on a fast machine
    sy.synth_hands("suction", n, 2, hands)
    out = tmp_path / "o"
    p = subprocess.Popen(
        [sys.executable, "-m", "mimicrete", "convert", str(hands), "--task", "suction",
         "--out", str(out), "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # a shell without job control starts background jobs with SIGINT ignored, and Python
        # keeps an ignored SIGINT: give convert the default, as a terminal's Ctrl-C finds it
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and not list(out.glob("*.mcap")):
        time.sleep(0.005)  # the first demo is done: interrupt during a later one
    p.send_signal(signal.SIGINT)
    rc = p.wait(120)
    err = p.stderr.read()
    no_traceback(subprocess.CompletedProcess([], rc, "", err))
    assert rc == 130 and "mimicrete convert: interrupted" in err, (rc, err)
    assert not list(out.glob("*.partial")) and not list(out.glob("*.lock"))
    done = sorted(out.glob("*.mcap"))
    assert 1 <= len(done) < n and demos.load(out).num_episodes == len(done)
