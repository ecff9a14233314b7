"""The hand-written stubs `python/mimicrete/_native.pyi` against the built extension module.

`mypy.stubtest` imports `mimicrete._native` and compares every runtime name, signature (argument
names, kinds, defaults), class and property with the stub; a second check type-checks user code
against the stubs with mypy, including calls that must be rejected.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import mimicrete
import mimicrete._native as native

ROOT = Path(__file__).resolve().parent.parent
PKG = Path(mimicrete.__file__).resolve().parent
ALLOWLIST = ROOT / ".mypy-stubtest-allowlist"

pytest.importorskip("mypy")


def _run(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", *args], cwd=cwd, capture_output=True, text=True, timeout=900
    )


def test_stub_files_ship_with_the_package():
    assert (PKG / "py.typed").is_file()
    assert (PKG / "_native.pyi").is_file()
    # The stub's __all__ is the runtime one (stubtest checks names; this checks the order too).
    import ast

    tree = ast.parse((PKG / "_native.pyi").read_text())
    stub_all = next(
        ast.literal_eval(node.value)
        for node in tree.body
        if isinstance(node, ast.Assign)
        and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets)
    )
    assert stub_all == list(native.__all__)


def test_stubtest_passes(tmp_path):
    args = ["mypy.stubtest", "mimicrete._native", "--mypy-config-file", str(tmp_path / "none.ini")]
    (tmp_path / "none.ini").write_text("[mypy]\n")
    if ALLOWLIST.exists():
        args += ["--allowlist", str(ALLOWLIST)]
    r = _run(args, cwd=ROOT)
    assert r.returncode == 0, f"stubtest failed:\n{r.stdout}\n{r.stderr}"
    assert "Success" in r.stdout, r.stdout


GOOD = """
import numpy as np
from numpy.typing import NDArray
import mimicrete._native as n

q: NDArray[np.float64] = n.kin_fk(np.zeros(6), "ur3")
qs, ok = n.kin_ik_batch(np.zeros((2, 4, 4)), None, "ur3", threads=1)
okb: NDArray[np.bool_] = ok
models: list[str] = n.kin_models()
env = n.SimEnv("TileSuction", seed=3)
obs: NDArray[np.float32] = env.reset(seed=1)
obs, reward, terminated, truncated, info = env.step(np.zeros(env.act_dim))
r: float = reward
installed: bool = info["installed"]
venv = n.SimVecEnv("suction", 4, num_threads=1)
out = venv.step(np.zeros((4, venv.act_dim), np.float32))
final_obs: NDArray[np.float32] = out[4]
steps: int = n.sim_constants()["MAX_EPISODE_STEPS"]
try:
    n.kin_ik(np.eye(4), None, "ur3")
except n.IkError as e:
    err: n.MimicreteError = e
with n.DemoWriter("x.mcap", {"task": "TileSuction"}) as w:
    w.write_event(0.0, "pick")
rewards: NDArray[np.float32] = n.demo_read("x.mcap")["rewards"]
"""

# Each line must be rejected by mypy (checked line by line).
BAD = """
import numpy as np
import mimicrete._native as n

n.kin_fk(np.zeros(6))
n.kin_ik(np.eye(4), None, "ur3", tolerance=1e-6)
s: str = n.SimEnv("TileSuction").obs_dim
n.SimEnv("TileSuction").act_dim = 3
x: int = n.demo_load("d")["nope"]
n.SimVecEnv("suction", num_envs="4")
"""


def test_mypy_checks_code_against_the_stubs(tmp_path):
    (tmp_path / "good.py").write_text(textwrap.dedent(GOOD))
    (tmp_path / "bad.py").write_text(textwrap.dedent(BAD))
    r = _run(
        [
            "mypy",
            "--strict",
            "--no-error-summary",
            "--config-file",
            "",
            "--cache-dir",
            str(ROOT / ".mypy_cache"),
            "good.py",
            "bad.py",
        ],
        cwd=tmp_path,
    )
    lines = [ln for ln in r.stdout.splitlines() if ": error:" in ln]
    assert not [ln for ln in lines if ln.startswith("good.py")], r.stdout + r.stderr
    bad_lines = {
        i + 1
        for i, ln in enumerate(textwrap.dedent(BAD).splitlines())
        if ln.strip() and not ln.startswith("import")
    }
    flagged = {int(ln.split(":")[1]) for ln in lines if ln.startswith("bad.py")}
    assert flagged == bad_lines, r.stdout + r.stderr
