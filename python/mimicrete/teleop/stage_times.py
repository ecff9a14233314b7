"""How stale the hand was: when each live control step's hand frame passed each stage.

A frame is captured and sent by the page (its own clock: ``t`` and ``sent_ms``), received by the
server, answered with a state (the server's clock), and that state is received by the page, which
acknowledges it with an ``ack`` message (docs/formats.md §3). Once a frame's state is
acknowledged, or once it has waited :data:`ACK_WAIT` answers, or when the episode ends, every
control step the frame ran gets a ``/teleop/stage_times`` message in the demo
(``DemoWriter.write_stage_times``). Only differences within one clock mean anything; the stages
:func:`mimicrete.demos.stage_durations` derives from them are what ``mimicrete inspect`` prints.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Answers kept waiting for the page's acknowledgement (~0.7 s of a 90 Hz stream); older ones are
#: written without a page receive time.
ACK_WAIT = 64


@dataclass
class _Answer:
    steps: list[int]
    capture_ms: float
    sent_ms: float
    server_recv_ms: float
    state_sent_ms: float | None = None


class StageClock:
    """One recording's stage times, written into its demo through ``writer``."""

    def __init__(self, writer: Any) -> None:
        self.w = writer
        self._waiting: OrderedDict[int, _Answer] = OrderedDict()

    def answered(
        self, seq: int, steps: list[int], capture_ms: float, sent_ms: float, recv_ms: float
    ) -> None:
        """Frame ``seq`` (captured at ``capture_ms``, sent at ``sent_ms``: the page's clock;
        received at ``recv_ms``: the server's) ran control ``steps``."""
        if steps:
            self._waiting[seq] = _Answer(steps, capture_ms, sent_ms, recv_ms)
            while len(self._waiting) > ACK_WAIT:
                self._write(*self._waiting.popitem(last=False), None)

    def state_sent(self, seq: int, ms: float) -> None:
        """The state answering frame ``seq`` went to the socket at ``ms`` (the server's clock)."""
        a = self._waiting.get(seq)
        if a is not None:
            a.state_sent_ms = ms

    def acked(self, states: list[tuple[int, float]]) -> None:
        """The page received the states of frames ``seq`` at ``ms`` (its clock)."""
        for seq, ms in states:
            a = self._waiting.pop(seq, None)
            if a is not None:
                self._write(seq, a, ms)

    def flush(self) -> None:
        """The episode ends: what is still waiting is written without a page receive time."""
        while self._waiting:
            self._write(*self._waiting.popitem(last=False), None)

    def _write(self, seq: int, a: _Answer, page_ms: float | None) -> None:
        for step in a.steps:
            self.w.write_stage_times(
                step, seq, a.capture_ms, a.sent_ms, a.server_recv_ms, a.state_sent_ms, page_ms
            )


def parse_ack(msg: dict[str, Any]) -> list[tuple[int, float]]:
    """The ``states`` of an ``ack`` message: ``[[seq, page_recv_ms], ...]``. Raises ValueError
    naming what is wrong."""
    states = msg.get("states")
    if not isinstance(states, list):
        raise ValueError(f"ack: states must be a list of [seq, ms], got {states!r}")
    out = []
    for i, s in enumerate(states):
        ok = isinstance(s, list) and len(s) == 2
        if ok:
            seq, ms = s
            ok = isinstance(seq, int) and seq >= 0 and isinstance(ms, int | float)
        if not ok or not np.isfinite(ms):
            raise ValueError(f"ack: states[{i}] must be [seq, ms], got {s!r}")
        out.append((seq, float(ms)))
    return out
