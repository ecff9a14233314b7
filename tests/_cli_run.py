"""The real command line in a subprocess, for the tests that go through it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import mimicrete


def run_cli(
    *args: str, cwd: Path | None = None, timeout: float = 300
) -> subprocess.CompletedProcess[str]:
    """``python -m mimicrete ARGS`` with this checkout's package first on ``PYTHONPATH``; the
    output captured as text."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(mimicrete.__file__).parent.parent), env.get("PYTHONPATH", "")]
    )
    return subprocess.run(
        [sys.executable, "-m", "mimicrete", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=timeout,
    )
