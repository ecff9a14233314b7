"""Bad input to `mimicrete export`: one line on stderr, exit 2, nothing written; through the
real CLI entry point."""

from __future__ import annotations

import shutil
import subprocess
import sys

import numpy as np
import pytest

from mimicrete.cli import main as cli_main
from mimicrete.export import ExportError, source


def _run(capsys, *args: str) -> tuple[int, str]:
    code = cli_main(["export", *args])
    err = capsys.readouterr().err
    return code, err


def _one_line_error(code: int, err: str, *needles: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("mimicrete export: error: ")
    for n in needles:
        assert n in lines[0], lines[0]


@pytest.mark.parametrize("fmt", ["lerobot", "minari"])
def test_mixed_tasks(demos3, grip_demo, tmp_path, capsys, fmt):
    mixed = tmp_path / "mixed"
    shutil.copytree(demos3, mixed)
    for f in grip_demo.glob("*.mcap"):
        shutil.copy(f, mixed / f.name)
    out = tmp_path / "out"
    code, err = _run(capsys, str(mixed), "--format", fmt, "--out", str(out))
    _one_line_error(code, err, "2 tasks", "TileSuction: 3", "BlockGrip: 1", "one task")
    assert not out.exists()
    assert list(tmp_path.glob(".out.*")) == []


def test_damaged_demo(demos3, tmp_path, capsys):
    bad = tmp_path / "bad"
    shutil.copytree(demos3, bad)
    victim = sorted(bad.glob("*.mcap"))[1]
    data = victim.read_bytes()
    victim.write_bytes(data[: len(data) // 2])  # cut in the middle, as a crash would
    out = tmp_path / "out"
    code, err = _run(capsys, str(bad), "--format", "lerobot", "--out", str(out))
    _one_line_error(code, err, victim.name, "damaged demo")
    assert not out.exists()


def test_existing_output(demos3, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    for fmt in ("lerobot", "minari"):
        code, err = _run(capsys, str(demos3), "--format", fmt, "--out", str(out))
        _one_line_error(code, err, str(out), "exists already")
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_no_demos_and_missing_dir(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    code, err = _run(capsys, str(empty), "--format", "lerobot", "--out", str(tmp_path / "o"))
    _one_line_error(code, err, "no *.mcap demos")
    missing = str(tmp_path / "nope")
    code, err = _run(capsys, missing, "--format", "minari", "--out", str(tmp_path / "o"))
    _one_line_error(code, err, "no such directory")


def test_bad_format_is_argparse_error(demos3, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        cli_main(["export", str(demos3), "--format", "rlds", "--out", str(tmp_path / "o")])
    assert e.value.code == 2
    assert "invalid choice: 'rlds'" in capsys.readouterr().err


def test_replay_mismatch_is_reported(demos3):
    from mimicrete import demos

    f = sorted(demos3.glob("*.mcap"))[0]
    ep = demos.read(f)
    obs = np.array(ep["obs"], dtype=np.float32)
    obs[5, 2] += 1e-3  # a demo from another simulator would differ like this
    with pytest.raises(ExportError, match=r"step 5 \(max difference 0\.001\)"):
        source._replay(f, "TileSuction", int(ep["meta"]["seed"]), obs, ep["actions"], ep)
    seed = int(ep["meta"]["seed"]) + 1
    with pytest.raises(ExportError, match="does not match this simulator"):
        source._replay(f, "TileSuction", seed, np.asarray(ep["obs"]), ep["actions"], ep)


def test_subprocess_exit_code(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "mimicrete",
            "export",
            str(empty),
            "--format",
            "lerobot",
            "--out",
            str(tmp_path / "o"),
        ],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 2
    assert r.stderr.strip() == f"mimicrete export: error: {empty}: no *.mcap demos"
