"""The package reads by name: no import cycle anywhere in ``mimicrete`` (module-level or inside
functions), no module over 600 lines, the CLI imports no torch to answer ``--help``,
``python -m mimicrete.experiments`` answers."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[2] / "python" / "mimicrete"
MAX_LINES = 600


def _modules() -> dict[str, Path]:
    """Every module of the package (``static/`` holds the built web page, not Python)."""
    out = {}
    for p in sorted(PKG.rglob("*.py")):
        rel = p.relative_to(PKG.parent).with_suffix("")
        parts = list(rel.parts[:-1]) if p.stem == "__init__" else list(rel.parts)
        out[".".join(parts)] = p
    return out


def _imports(name: str, path: Path) -> set[str]:
    """Every module ``name`` imports, anywhere in the file (relative imports resolved)."""
    is_pkg = path.stem == "__init__"
    base = name.split(".") if is_pkg else name.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                root = base[: len(base) - node.level + 1]
                mod = ".".join(root + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            found.add(mod)
            found.update(f"{mod}.{a.name}" for a in node.names)  # `from . import x`
    return found


def test_no_import_cycle_in_the_package():
    mods = _modules()
    graph = {m: {i for i in _imports(m, p) if i in mods and i != m} for m, p in mods.items()}
    # a package's __init__ is imported by every submodule: only edges out of it can close a cycle
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for n in sorted(graph[m]):
            if m.startswith(n + "."):
                continue  # a submodule importing its own package's name
            if state.get(n) == 1:
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(n) :] + [n]))
            if n not in state:
                visit(n)
        stack.pop()
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m)
    assert "mimicrete.learn.trainer" in graph and "mimicrete.experiments.sweep" in graph


def test_no_module_over_600_lines():
    files = list(_modules().values())
    long = {
        str(p.relative_to(PKG)): n
        for p in files
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    }
    assert long == {}


def test_a_module_run_with_python_m_logs_under_the_package_logger():
    """Run as ``python -m``, a module is ``__main__``: its ``getLogger(__name__)`` is outside the
    ``mimicrete`` logger that :func:`mimicrete.console.show_messages` shows, so what it logs is
    lost (``gestures.shipped`` and ``experiments.peers`` printed nothing). Such a module names its
    logger; this finds any that does not."""
    lost = []
    for name, p in _modules().items():
        tree = ast.parse(p.read_text())
        runs_as_main = any(
            isinstance(n, ast.If) and "__main__" in ast.unparse(n.test) for n in tree.body
        )
        for n in ast.walk(tree):
            if (
                runs_as_main
                and isinstance(n, ast.Call)
                and ast.unparse(n.func).endswith("getLogger")
                and [ast.unparse(a) for a in n.args] == ["__name__"]
            ):
                lost.append(name)
    assert lost == []


def _python(code: str) -> subprocess.CompletedProcess:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(PKG.parent) + os.pathsep + env.get("PYTHONPATH", "")
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )


def test_the_cli_parser_imports_no_torch():
    r = _python(
        "import sys, argparse\n"
        "from mimicrete.cli import build_parser\n"
        "build_parser()\n"
        "import mimicrete.learn, mimicrete.experiments\n"
        "print(sorted(k for k in sys.modules if k == 'torch' or k.startswith('torch.')))\n"
    )
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"


def test_experiments_entry_point_answers():
    env = dict(os.environ)
    env["PYTHONPATH"] = str(PKG.parent) + os.pathsep + env.get("PYTHONPATH", "")
    for mod in ("mimicrete.experiments", "mimicrete.experiments.report"):
        r = subprocess.run(
            [sys.executable, "-m", mod, "--help"], capture_output=True, text=True, env=env,
            timeout=300,
        )  # fmt: skip
        assert r.returncode == 0, r.stderr
        assert "usage: python -m " + mod in r.stdout


def test_every_module_imports():
    import importlib

    for name in _modules():
        if not name.endswith("__main__"):  # running those is running the program
            importlib.import_module(name)
