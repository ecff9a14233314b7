"""Where the package's log messages go when a person runs one of its programs.

The library logs (``logging.getLogger(__name__)``, all under the ``mimicrete`` logger) and prints
nothing. A program (``mimicrete train``, ``mimicrete eval``, ``mimicrete teleop``,
``python -m mimicrete.experiments`` and the experiments' other ``main()`` functions, a sweep's
trial) calls :func:`show_messages` once; a message then reads as it did when the library
printed it: information on stdout, a warning on stderr as ``warning: <message>``. A program that
does not call it gets Python's default: warnings on stderr, information dropped.
"""

from __future__ import annotations

import logging
import sys

LOGGER = "mimicrete"


class _Terminal(logging.Handler):
    """A message on stdout (information) or stderr (``warning: ...`` and worse), written to the
    ``sys.stdout`` / ``sys.stderr`` of the moment: the CLI swaps in a pipe-safe stdout while a
    command runs, and pytest's capture swaps both."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = self.format(record)
            if record.levelno >= logging.WARNING:
                stream, text = sys.stderr, f"{record.levelname.lower()}: {text}"
            else:
                stream = sys.stdout
            stream.write(text + "\n")
            stream.flush()
        except Exception:  # noqa: BLE001 - logging's own convention: report, never raise
            self.handleError(record)


def show_messages() -> None:
    """Show the package's messages of level INFO and above on the terminal (once per process,
    however often it is called)."""
    logger = logging.getLogger(LOGGER)
    if not any(isinstance(h, _Terminal) for h in logger.handlers):
        logger.addHandler(_Terminal())
    logger.setLevel(logging.INFO)
