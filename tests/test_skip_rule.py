"""The rule of tests/conftest.py: a full run (``--runslow``) fails on a skip that is not listed
in ``ALLOWED_SKIPS``, in a test or in a whole module; a quick run still skips."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

CONFTEST = Path(__file__).with_name("conftest.py")


def _pytest(folder: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *args],
        cwd=folder,
        capture_output=True,
        text=True,
        timeout=300,
    )


def _suite(tmp_path: Path) -> Path:
    (tmp_path / "pytest.ini").write_text("[pytest]\n")  # this folder is the rootdir
    (tmp_path / "conftest.py").write_text(CONFTEST.read_text())
    (tmp_path / "test_a.py").write_text(
        "import pytest\n\n"
        "def test_ok():\n    pass\n\n"
        "def test_missing_piece():\n    pytest.skip('the simulator is not built')\n\n"
        "@pytest.mark.xfail(reason='known')\ndef test_known():\n    assert False\n"
    )
    return tmp_path


def test_a_full_run_fails_on_an_unlisted_skip(tmp_path):
    d = _suite(tmp_path)
    full = _pytest(d, "--runslow")
    assert full.returncode == 1, full.stdout
    assert "1 failed, 1 passed, 1 xfailed" in full.stdout, full.stdout
    assert "without being listed" in full.stdout and "the simulator is not built" in full.stdout
    quick = _pytest(d)
    assert quick.returncode == 0, quick.stdout
    assert "1 passed, 1 skipped, 1 xfailed" in quick.stdout, quick.stdout


def test_a_full_run_fails_on_a_skipped_module(tmp_path):
    d = _suite(tmp_path)
    (d / "test_b.py").write_text("import pytest\n\npytest.importorskip('no_such_module_xyz')\n")
    full = _pytest(d, "--runslow", "test_b.py")
    assert full.returncode == 1, full.stdout
    assert "test_b.py: could not import 'no_such_module_xyz'" in full.stdout, full.stdout
    quick = _pytest(d)
    assert quick.returncode == 0 and "1 passed, 2 skipped, 1 xfailed" in quick.stdout, quick.stdout
