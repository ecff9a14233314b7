"""Probes of issue 24 (items 1-8 and 16) through the real CLI (a subprocess running
``python -m mimicrete``) and the public API: nothing hangs on an input that is not a regular
file, a hand log says one thing per field, a demo's provenance hash covers exactly the bytes
converted, a file name that is not UTF-8 is named and converted, bad input exits 2 without a
warning or traceback first, loading a demo checks what ``inspect`` checks, salvage survives a
damaged leading magic, a dangling ``x.mcap`` link is refused by name, and an MCAP file of another
program is said not to be a demo.

Probes that held before the fixes sit beside the ones that failed, so that none regresses; the
docstring of each test says which kind it is (``held`` / ``fixed``).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import mimicrete
from _cli_run import run_cli as run
from mimicrete import LogFormatError, demos
from mimicrete import demonstrator as sy

#: A probe that hangs fails after this many seconds instead of blocking the suite.
HANG_S = 30


def no_traceback(p: subprocess.CompletedProcess[str]) -> None:
    assert "Traceback" not in p.stderr and "Warning" not in p.stderr, p.stderr


def run_py(code: str, *args: str, timeout: float = HANG_S) -> subprocess.CompletedProcess[str]:
    """``python -c CODE ARGS`` with this checkout's package first on the path (a probe that
    could block runs in a child, so that a hang is a timeout, not a stuck test run)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(mimicrete.__file__).parent.parent), env.get("PYTHONPATH", "")]
    )
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code), *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=timeout,
    )


@pytest.fixture(scope="module")
def hands(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("hands")
    sy.synth_hands("suction", 2, 0, d)
    return d


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory, hands: Path) -> Path:
    """Two demos converted through the CLI (never modified: tests copy what they damage)."""
    out = tmp_path_factory.mktemp("demos")
    p = run("convert", str(hands), "--task", "suction", "--out", str(out), "--no-progress")
    assert p.returncode == 0, p.stderr
    return out


def logs(hands: Path) -> list[Path]:
    return sorted(hands.glob("*.jsonl"))


def copy_demo(demo_dir: Path, dst: Path) -> Path:
    dst.mkdir(parents=True, exist_ok=True)
    src = sorted(demo_dir.glob("*.mcap"))[0]
    out = dst / src.name
    out.write_bytes(src.read_bytes())
    return out


def convert(src: Path | str, out: Path, *more: str) -> subprocess.CompletedProcess[str]:
    return run(
        "convert",
        str(src),
        "--task",
        "suction",
        "--out",
        str(out),
        "--no-progress",
        *more,
        timeout=HANG_S,
    )


# ---- 1. nothing hangs: anything not a regular file is refused with its name -------------------


def test_a_fifo_in_a_log_folder_is_refused_by_name_and_the_rest_converted(tmp_path, hands):
    """fixed: ``convert d`` blocked forever on ``d/b.jsonl`` being a named pipe."""
    d = tmp_path / "d"
    d.mkdir()
    (d / "a.jsonl").write_bytes(logs(hands)[0].read_bytes())
    os.mkfifo(d / "b.jsonl")
    p = convert(d, tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2, p.stderr
    assert f"{d / 'b.jsonl'}:1: not a regular file (a named pipe)" in p.stderr
    assert [f.name for f in (tmp_path / "o").iterdir()] == ["a.mcap"]


def test_a_fifo_given_as_the_log_is_refused(tmp_path):
    """fixed: ``convert fifo.jsonl`` blocked."""
    os.mkfifo(tmp_path / "x.jsonl")
    p = convert(tmp_path / "x.jsonl", tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2 and "x.jsonl:1: not a regular file (a named pipe)" in p.stderr


@pytest.mark.parametrize("flags", [[], ["--no-verify"], ["--json"]])
def test_inspect_refuses_a_fifo(tmp_path, flags):
    """fixed: ``inspect x.mcap`` on a named pipe blocked (in the Rust check and in the mcap
    reader)."""
    os.mkfifo(tmp_path / "x.mcap")
    p = run("inspect", *flags, str(tmp_path / "x.mcap"), timeout=HANG_S)
    no_traceback(p)
    assert p.returncode == 1
    said = json.loads(p.stdout)["error"] if "--json" in flags else p.stdout
    assert f"{tmp_path / 'x.mcap'}: not a regular file (a named pipe)" in said


def test_load_refuses_a_fifo_among_demos(tmp_path, demo_dir):
    """fixed: a named pipe ``x.mcap`` in a demo folder was skipped without a word."""
    d = tmp_path / "d"
    copy_demo(demo_dir, d)
    os.mkfifo(d / "x.mcap")
    p = run_py(
        """
        import sys
        from mimicrete import LogFormatError, demos
        try:
            demos.load(sys.argv[1])
        except LogFormatError as e:
            print(e)
        """,
        str(d),
    )
    assert p.returncode == 0, p.stderr
    assert f"{d / 'x.mcap'}: not a regular file (a named pipe)" in p.stdout


def test_a_character_device_is_not_read_as_a_log(tmp_path):
    """fixed: ``/dev/zero`` was read until memory ran out; ``/dev/null`` read as an empty log."""
    p = convert("/dev/null", tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2 and "/dev/null:1: not a regular file (a character device)" in p.stderr


# ---- 2. duplicated JSON keys ----------------------------------------------------------------


def _dup_header(line: str) -> str:
    return line[:-1] + ',"handedness":"left"}'


@pytest.mark.parametrize(
    ("where", "edit", "line", "says"),
    [
        (
            "header",
            lambda ls: [_dup_header(ls[0]), *ls[1:]],
            1,
            'header: duplicate key "handedness"',
        ),
        (
            "frame t",
            lambda ls: [*ls[:5], ls[5].replace('{"t":', '{"t":99.0,"t":', 1), *ls[6:]],
            6,
            'duplicate key "t"',
        ),
        (
            "frame tracked",
            lambda ls: [*ls[:7], ls[7][:-1] + ',"tracked":false}', *ls[8:]],
            8,
            'duplicate key "tracked"',
        ),
        (
            "nested in extra",
            lambda ls: [ls[0].replace('"extra":{', '"extra":{"a":1,"a":2,', 1), *ls[1:]],
            1,
            'header: duplicate key "a"',
        ),
    ],
)
def test_duplicated_keys_are_refused(tmp_path, hands, where, edit, line, says):
    """fixed: the last of two equal keys won (a right hand converted as a left one, exit 0)."""
    lines = logs(hands)[0].read_text().splitlines()
    bad = tmp_path / "dup.jsonl"
    bad.write_text("\n".join(edit(lines)) + "\n")
    p = convert(bad, tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2, (where, p.stdout, p.stderr)
    assert f"{bad}:{line}: {says}" in p.stderr
    assert not (tmp_path / "o").exists() or not list((tmp_path / "o").iterdir())


def test_lenient_mode_skips_a_frame_with_a_duplicated_key(tmp_path, hands):
    """fixed: ``--lenient`` kept the frame (with the second value)."""
    lines = logs(hands)[0].read_text().splitlines()
    lines[5] = lines[5].replace('{"t":', '{"t":99.0,"t":', 1)
    bad = tmp_path / "dup.jsonl"
    bad.write_text("\n".join(lines) + "\n")
    p = convert(bad, tmp_path / "o", "--lenient")
    assert p.returncode == 0, p.stderr
    assert "1 bad lines skipped" in p.stdout


def test_the_same_key_in_different_objects_is_fine(hands):
    """held: every frame has its own ``t`` (and joints nest arrays, not objects)."""
    log = mimicrete.hands.parse(logs(hands)[0])
    assert len(log) > 100 and log.header["handedness"] == "right"


# ---- 3. provenance: the hash covers exactly the bytes read ----------------------------------


def test_the_handlog_hash_covers_the_bytes_converted_not_what_was_appended(tmp_path, hands):
    """fixed: the writer hashed the file again when the demo was opened, after the log had grown
    (the hash covered 800 lines, 546 frames were converted)."""
    log = tmp_path / "take.jsonl"
    original = logs(hands)[0].read_bytes()
    log.write_bytes(original)
    more = original.splitlines(keepends=True)[-1]
    # The real CLI, with the log appended to between its parse and the demo being opened (where
    # the gesture model is loaded): a recorder still writing the file.
    p = run_py(
        """
        import sys
        from mimicrete import cli, gestures

        log, more = sys.argv[1], sys.argv[2]
        load_default = gestures.load_default

        def appending(task):
            with open(log, "a") as f:
                f.write(more * 10)
            return load_default(task)

        gestures.load_default = appending
        sys.exit(cli.main(sys.argv[3:]))
        """,
        str(log),
        more.decode(),
        "convert",
        str(log),
        "--task",
        "suction",
        "--out",
        str(tmp_path / "o"),
        "--no-progress",
        timeout=300,
    )
    assert p.returncode == 0, p.stderr
    assert log.read_bytes() != original  # it did grow
    meta = demos.load(tmp_path / "o").metas[0]
    assert meta["source_handlog_sha256"] == hashlib.sha256(original).hexdigest()


def test_a_converted_demo_names_its_log_and_hash(demo_dir, hands):
    """held: the hash of an unchanged log is the file's."""
    d = demos.load(demo_dir)
    for meta, log in zip(d.metas, logs(hands), strict=True):
        assert meta["source_handlog"] == os.path.relpath(log, demo_dir)  # relative to the demo
        assert meta["source_handlog_sha256"] == hashlib.sha256(log.read_bytes()).hexdigest()


# ---- 4. a file name that is not UTF-8 ---------------------------------------------------------


def test_a_non_utf8_file_name_is_converted_and_named(tmp_path, hands):
    """fixed: ``take\\xff.jsonl`` failed with "str is not JSON data", not naming the file."""
    d = tmp_path / "d"
    d.mkdir()
    raw = os.fsencode(d) + b"/take\xff.jsonl"
    with open(raw, "wb") as f:
        f.write(logs(hands)[0].read_bytes())
    p = convert(d, tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 0, p.stderr
    assert "take\\xff.jsonl: " in p.stdout
    assert os.listdir(os.fsencode(tmp_path / "o")) == [b"take\xff.mcap"]
    loaded = demos.load(tmp_path / "o")
    meta = loaded.metas[0]
    assert meta["source_handlog"] == "../d/take\\xff.jsonl"  # relative to the demo's folder
    assert meta["source_handlog_sha256"] == hashlib.sha256(logs(hands)[0].read_bytes()).hexdigest()
    assert os.fsencode(loaded.files[0]).endswith(b"/take\xff.mcap")  # the real name


def test_a_demo_with_a_non_utf8_name_is_read_for_export(tmp_path, demo_dir):
    """held: export's reader found such a demo under its real name (the listing must keep it;
    writing such a name into a LeRobot dataset still fails, which is not fixed here)."""
    from mimicrete.export.source import read_demo_dir

    d = tmp_path / "d"
    d.mkdir()
    src = sorted(demo_dir.glob("*.mcap"))[0]
    with open(os.fsencode(d) + b"/take\xff.mcap", "wb") as f:
        f.write(src.read_bytes())
    assert os.fsencode(demos.files(d)[0]).endswith(b"/take\xff.mcap")
    got = read_demo_dir(d)
    assert len(got.episodes) == 1 and os.fsencode(got.episodes[0].file).endswith(b"\xff.mcap")


def test_a_bad_log_with_a_non_utf8_name_is_named(tmp_path):
    """fixed: the message of a failing log must name it (readably)."""
    d = tmp_path / "d"
    d.mkdir()
    with open(os.fsencode(d) + b"/bad\xfe.jsonl", "w") as f:
        f.write('{"format": "nope"}\n')
    p = convert(d, tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2 and "bad" in p.stderr and 'unknown format "nope"' in p.stderr


# ---- 5. exit codes and warnings ---------------------------------------------------------------


def test_a_malformed_log_exits_2(tmp_path):
    """fixed: ``convert`` exited 1 on bad input; the CLI's rule (and the other commands): 2."""
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"format": "nope"}\n')
    p = convert(bad, tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2 and f'{bad}:1: unknown format "nope" in header' in p.stderr


def test_huge_coordinates_are_refused_by_the_parser_without_a_warning(tmp_path, hands):
    """fixed: every coordinate at 1e300 was refused only after a numpy RuntimeWarning (and its
    source line) were printed."""
    lines = logs(hands)[0].read_text().splitlines()
    frames = []
    for x in lines[1:]:
        f = json.loads(x)
        f["joints"] = [[1e300, 1e300, 1e300] for _ in f["joints"]]
        frames.append(json.dumps(f))
    bad = tmp_path / "huge.jsonl"
    bad.write_text("\n".join([lines[0], *frames]) + "\n")
    p = convert(bad, tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2
    assert f"{bad}:2: joint 0 coordinate x is 1e300 m, out of range" in p.stderr


def test_a_nan_coordinate_is_still_refused_with_its_line(tmp_path, hands):
    """held: NaN is named at its line."""
    lines = logs(hands)[0].read_text().splitlines()
    f = json.loads(lines[3])
    f["joints"][0][0] = float("nan")
    lines[3] = json.dumps(f)  # Python writes a bare NaN
    bad = tmp_path / "nan.jsonl"
    bad.write_text("\n".join(lines) + "\n")
    p = convert(bad, tmp_path / "o")
    no_traceback(p)
    assert p.returncode != 0 and f"{bad}:4:" in p.stderr


def test_a_missing_log_exits_2(tmp_path):
    """held."""
    p = convert(tmp_path / "nothing.jsonl", tmp_path / "o")
    no_traceback(p)
    assert p.returncode == 2 and "nothing.jsonl" in p.stderr


# ---- 6. loading checks what inspect checks ----------------------------------------------------


def _flip_in_last_record(path: Path, key: bytes, index: int, bit: int) -> str:
    """Flip one bit of the value of ``key`` in the last metadata record that has it (the
    ``episode`` record); the value after the flip."""
    b = bytearray(path.read_bytes())
    i = b.rfind(key)
    n = int.from_bytes(b[i + len(key) : i + len(key) + 4], "little")
    at = i + len(key) + 4
    b[at + index] ^= bit
    path.write_bytes(bytes(b))
    return b[at : at + n].decode()


@pytest.mark.parametrize(
    ("key", "index", "bit", "value", "says"),
    [
        (b"control_dt", 3, 0x01, "0.05", "data section CRC mismatch"),
        (b"success", 1, 0x02, "tpue", 'metadata record "episode": success is "tpue"'),
    ],
)
def test_one_flipped_bit_in_episode_metadata_is_refused_by_load_and_export(
    tmp_path, demo_dir, key, index, bit, value, says
):
    """fixed: ``load`` returned the changed value and ``export`` exited 0 (fps 20, success
    False); only ``inspect`` flagged the file."""
    f = copy_demo(demo_dir, tmp_path / "d")
    assert _flip_in_last_record(f, key, index, bit) == value
    with pytest.raises(LogFormatError, match=says) as e:
        demos.load(f)
    assert str(f) in str(e.value)
    p = run("export", str(tmp_path / "d"), "--format", "lerobot", "--out", str(tmp_path / "x"))
    no_traceback(p)
    assert p.returncode == 2 and f"{f}: damaged demo" in p.stderr
    assert not (tmp_path / "x").exists()
    p = run("inspect", str(f))  # held: inspect flagged it already
    assert p.returncode == 1 and "CRC mismatch" in p.stdout


def test_a_bad_metadata_value_is_refused_even_without_crcs(tmp_path):
    """fixed: ``success`` = "tpue" in a file whose CRCs are off (another writer) was loaded."""
    from mcap.writer import CompressionType, Writer

    from mimicrete import _native

    f = tmp_path / "nocrc.mcap"
    with open(f, "wb") as out:
        w = Writer(out, compression=CompressionType.NONE, enable_crcs=False, enable_data_crcs=False)
        w.start()
        w.add_metadata("episode", {"success": "tpue", "task": "suction"})
        w.finish()
    with pytest.raises(LogFormatError, match='metadata record "episode": success is "tpue"'):
        _native.demo_read(str(f))
    assert any("success is" in x for x in demos.verify(f)["problems"])


def test_a_flipped_bit_inside_a_chunk_is_still_refused(tmp_path, demo_dir):
    """held: a chunk's own CRC."""
    f = copy_demo(demo_dir, tmp_path / "d")
    b = bytearray(f.read_bytes())
    b[len(b) // 3] ^= 0x10
    f.write_bytes(bytes(b))
    with pytest.raises(LogFormatError):
        demos.load(f)


def test_healthy_demos_still_load_inspect_and_export(tmp_path, demo_dir):
    """held."""
    d = demos.load(demo_dir)
    assert d.num_episodes == 2 and len(d) > 0
    p = run("inspect", *map(str, sorted(demo_dir.glob("*.mcap"))))
    assert p.returncode == 0 and p.stdout.count("integrity: OK") == 2


# ---- 7. salvage survives a damaged leading magic ------------------------------------------------


def test_salvage_recovers_a_demo_whose_leading_magic_has_a_flipped_bit(tmp_path, demo_dir):
    """fixed: one bit in byte 3 of the magic made salvage and ``salvage_to`` refuse ("bad
    magic"), and every intact step was lost."""
    f = copy_demo(demo_dir, tmp_path / "d")
    good = demos.read(f)
    b = bytearray(f.read_bytes())
    b[3] ^= 0x04
    f.write_bytes(bytes(b))
    msgs, rep = demos.salvage(f)
    assert rep["magic_damaged"] and rep["chunks_lost"] == 0 and len(msgs) > 0
    fixed = tmp_path / "fixed.mcap"
    demos.salvage_to(f, fixed)
    back = demos.read(fixed)
    assert len(back["rewards"]) == len(good["rewards"])
    assert (back["actions"] == good["actions"]).all()
    with pytest.raises(LogFormatError, match="leading magic is damaged.*salvage_to"):
        demos.load(f)
    p = run("inspect", str(f))
    no_traceback(p)
    assert p.returncode == 1 and "the leading magic is damaged" in p.stdout
    assert "salvage_to" in p.stdout


def test_a_file_that_is_not_mcap_is_still_refused_by_salvage(tmp_path):
    """held: the tolerance is for a flipped bit or two, not for another format."""
    f = tmp_path / "x.mcap"
    f.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(200))
    with pytest.raises(LogFormatError, match="bad magic"):
        demos.salvage(f)
    p = run("inspect", str(f))
    assert p.returncode == 1 and "bad magic" in p.stdout


# ---- 8. a dangling x.mcap link ---------------------------------------------------------------


def test_a_dangling_demo_link_is_refused_by_load_and_export(tmp_path, demo_dir):
    """fixed: ``demos.load`` (so train and export) skipped it without a word."""
    d = tmp_path / "d"
    copy_demo(demo_dir, d)
    (d / "x.mcap").symlink_to(tmp_path / "gone.mcap")
    with pytest.raises(LogFormatError, match="x.mcap: dangling symbolic link"):
        demos.load(d)
    assert [p.name for p in demos.files(d)] == [
        sorted(demo_dir.glob("*.mcap"))[0].name,
        "x.mcap",
    ]
    p = run("export", str(d), "--format", "lerobot", "--out", str(tmp_path / "x"))
    no_traceback(p)
    assert p.returncode == 2 and "x.mcap" in p.stderr and "dangling symbolic link" in p.stderr


def test_a_link_to_a_demo_is_loaded(tmp_path, demo_dir):
    """held: a symbolic link to a real demo is read like the file."""
    d = tmp_path / "d"
    d.mkdir()
    src = sorted(demo_dir.glob("*.mcap"))[0]
    (d / "linked.mcap").symlink_to(src)
    assert demos.load(d).num_episodes == 1


# ---- 16. an MCAP file of another program -----------------------------------------------------


def test_inspect_says_an_mcap_of_another_program_is_not_a_demo(tmp_path):
    """fixed: "integrity OK, steps=0", exit 0."""
    from mcap.writer import Writer

    f = tmp_path / "other.mcap"
    with open(f, "wb") as out:
        w = Writer(out)
        w.start(profile="", library="someone-else")
        sid = w.register_schema(name="Pose", encoding="jsonschema", data=b"{}")
        cid = w.register_channel(topic="/robot/pose", message_encoding="json", schema_id=sid)
        for k in range(3):
            w.add_message(cid, log_time=k, publish_time=k, data=b"{}")
        w.finish()
    p = run("inspect", str(f))
    no_traceback(p)
    assert p.returncode == 1
    assert f"{f}: not a mimicrete demo: no /demo/step channel (its topics: /robot/pose)" in p.stdout
    with pytest.raises(LogFormatError, match="not a mimicrete demo"):  # held
        demos.load(f)
