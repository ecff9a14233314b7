"""Shared options and fixtures, and the rule that a full run (``--runslow``, what ``make test``
and CI run) skips nothing: every skip there is a failure unless its reason starts with one of
:data:`ALLOWED_SKIPS`, each entry saying why that condition is real on a CI machine."""

from pathlib import Path

import pytest

#: reason prefix -> why such a skip may happen in a full run. Empty: on a machine set up by
#: ``make setup`` / ``make web`` / ``make export-venv`` every test's pieces exist, so a skip
#: there means a missing piece and fails.
ALLOWED_SKIPS: dict[str, str] = {}

_unexpected_collect_skips: list[str] = []


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False, help="run tests marked slow")
    parser.addoption(
        "--figures",
        metavar="DIR",
        default=None,
        help="also save the README's page screenshots into DIR (`make figures`: docs/figures);"
        " without it tests write only to temporary directories",
    )


def unexpected_skip(reason: str) -> bool:
    """Whether a skip with this reason fails a full (``--runslow``) run."""
    return not any(reason.startswith(p) for p in ALLOWED_SKIPS)


def _skip_reason(longrepr) -> str:
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2]).removeprefix("Skipped: ")
    return str(longrepr)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if not item.config.getoption("--runslow") or not rep.skipped or hasattr(rep, "wasxfail"):
        return
    reason = _skip_reason(rep.longrepr)
    if unexpected_skip(reason):
        rep.outcome = "failed"
        rep.longrepr = (
            f"skipped in a full run (--runslow) without being listed in "
            f"tests/conftest.py ALLOWED_SKIPS: {reason}"
        )


def pytest_collectreport(report):
    if report.skipped and unexpected_skip(_skip_reason(report.longrepr)):
        _unexpected_collect_skips.append(f"{report.nodeid}: {_skip_reason(report.longrepr)}")


def pytest_sessionfinish(session, exitstatus):
    if session.config.getoption("--runslow") and _unexpected_collect_skips:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if config.getoption("--runslow") and _unexpected_collect_skips:
        terminalreporter.section("modules skipped in a full run (not in ALLOWED_SKIPS)", red=True)
        for line in _unexpected_collect_skips:
            terminalreporter.line(line)


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: pass --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session")
def figures_dir(pytestconfig) -> Path | None:
    """Where the page tests save the README's screenshots (``--figures DIR``), else None."""
    d = pytestconfig.getoption("--figures")
    if d is None:
        return None
    out = Path(d).resolve()
    out.mkdir(parents=True, exist_ok=True)
    return out


@pytest.fixture(scope="session")
def scene_fn():
    """``(task, seed) -> mimicrete.synth.Scene``: the simulator's own scene
    (``synth.scene_from_env``; the package is always built with the simulator)."""
    from mimicrete import demonstrator as sy

    return sy.scene_from_env
