"""The library logs and the programs show it (issue 25 §2): after ``console.show_messages`` a
message of the package reads as when the library printed it, information on stdout and a warning
on stderr as ``warning: ...``; without it, nothing of level INFO is printed."""

from __future__ import annotations

import logging
import subprocess
import sys

from mimicrete import console


def test_information_goes_to_stdout_and_a_warning_to_stderr(capsys):
    console.show_messages()
    console.show_messages()  # once per process, however often a program calls it
    log = logging.getLogger("mimicrete.learn.some_module")
    log.info("demos: making 60")
    log.warning("a checkpoint passed over")
    out, err = capsys.readouterr()
    assert out == "demos: making 60\n"
    assert err == "warning: a checkpoint passed over\n"
    handlers = logging.getLogger(console.LOGGER).handlers
    assert sum(isinstance(h, console._Terminal) for h in handlers) == 1


def test_the_library_prints_nothing_by_itself():
    """A program that does not call show_messages: the information is dropped, a warning is
    Python's default (its text alone on stderr)."""
    code = (
        "import logging; from mimicrete.learn import demo_data\n"
        "demo_data.logger.info('an information'); demo_data.logger.warning('a warning')\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout == "" and r.stderr == "a warning\n"
