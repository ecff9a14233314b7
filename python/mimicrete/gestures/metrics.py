"""How a gesture model behaves on a stream: accuracy, flicker and latency, before and after the
session's smoother (:class:`~mimicrete.gestures.smoother.GestureSmoother`, ``n=7, k=5`` as
:class:`mimicrete.teleop.session.Session` runs it).

Definitions (per sequence; :func:`pool` sums them over sequences):

* The model is asked about tracked frames only, once each in order, as the session does; on an
  untracked frame the outputs hold.
* **accuracy**: share of tracked frames whose output is the true class.
* **held frames**: tracked frames not part of a change of gesture (``changing``); a *segment* is a
  run of frames with one true class. **flicker**: output changes between consecutive held frames
  of a segment, except the one change that first brings the output to the segment's class (a
  late but real change), per second of held frames.
* **latency**: for each true change (the frame where the label changes, half-way through the
  in-between shapes), the time from it to the first frame, from the start of that change's
  in-between shapes on, whose output is the new class; *missed* if that never happens before the
  next true change.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .sequences import GestureSequence
from .smoother import GestureSmoother


@dataclass
class StreamStats:
    """Counts behind the metrics (summable over sequences)."""

    frames: int = 0
    correct: int = 0
    held_frames: int = 0
    held_correct: int = 0
    held_seconds: float = 0.0
    flicker: int = 0
    latencies: list[float] = field(default_factory=list)
    missed: int = 0
    changes: int = 0

    def add(self, o: StreamStats) -> StreamStats:
        return StreamStats(
            self.frames + o.frames,
            self.correct + o.correct,
            self.held_frames + o.held_frames,
            self.held_correct + o.held_correct,
            self.held_seconds + o.held_seconds,
            self.flicker + o.flicker,
            self.latencies + o.latencies,
            self.missed + o.missed,
            self.changes + o.changes,
        )

    def summary(self) -> dict[str, Any]:
        lat = np.asarray(self.latencies) * 1000.0
        return {
            "accuracy": self.correct / max(self.frames, 1),
            "held_accuracy": self.held_correct / max(self.held_frames, 1),
            "flicker_per_s": self.flicker / max(self.held_seconds, 1e-9),
            "flicker": self.flicker,
            "held_s": self.held_seconds,
            "latency_ms_median": float(np.median(lat)) if len(lat) else float("nan"),
            "latency_ms_p90": float(np.percentile(lat, 90)) if len(lat) else float("nan"),
            "changes": self.changes,
            "missed": self.missed,
        }


def stream_outputs(model: Any, seq: GestureSequence) -> np.ndarray:
    """The model's raw class per frame, asked as the session asks (``reset()``, then
    ``predict_margin`` on each tracked frame in order); ``None`` on frames not asked or
    degenerate."""
    model.reset()
    out = np.full(len(seq), None, dtype=object)
    for k in np.flatnonzero(seq.tracked):
        out[k] = model.predict_margin(seq.joints[k], seq.handedness, seq.layout)[0]
    return out


def smooth(raw: np.ndarray, tracked: np.ndarray, n: int = 7, k: int = 5) -> np.ndarray:
    """The session's smoother over raw outputs (fed on tracked frames only)."""
    sm = GestureSmoother(n=n, k=k)
    out = np.full(len(raw), None, dtype=object)
    for i, r in enumerate(raw):
        out[i] = sm.update(r) if tracked[i] else sm.state
    return out


def _hold(out: np.ndarray, tracked: np.ndarray) -> np.ndarray:
    """Outputs held over untracked frames (the last answer stays)."""
    held = out.copy()
    last = None
    for i in range(len(held)):
        if tracked[i]:
            last = held[i]
        else:
            held[i] = last
    return held


def stream_stats(seq: GestureSequence, out: np.ndarray) -> StreamStats:
    """:class:`StreamStats` of per-frame outputs against the sequence's labels."""
    truth = np.asarray(seq.labels)
    tracked = np.asarray(seq.tracked, dtype=bool)
    changing = np.asarray(seq.changing, dtype=bool)
    out = _hold(np.asarray(out, dtype=object), tracked)
    hit = out == truth
    st = StreamStats(frames=int(tracked.sum()), correct=int((hit & tracked).sum()))
    held = tracked & ~changing
    st.held_frames = int(held.sum())
    st.held_correct = int((hit & held).sum())
    dt = float(np.median(np.diff(seq.t))) if len(seq.t) > 1 else 0.0
    st.held_seconds = st.held_frames * dt
    bounds = np.flatnonzero(truth[1:] != truth[:-1]) + 1
    starts = np.concatenate([[0], bounds])
    ends = np.concatenate([bounds, [len(truth)]])
    for a, b in zip(starts, ends, strict=True):
        idx = a + np.flatnonzero(held[a:b])
        if len(idx) == 0:
            continue
        o = out[idx]
        n_changes = int(np.sum(o[1:] != o[:-1]))
        first = np.flatnonzero(o == truth[a])
        if len(first) and first[0] > 0:
            n_changes -= 1  # the late but real change
        st.flicker += n_changes
    for a, b in zip(starts[1:], ends[1:], strict=True):
        st.changes += 1
        s = a
        while s > 0 and changing[s - 1]:
            s -= 1
        reach = s + np.flatnonzero(out[s:b] == truth[a])
        if len(reach) == 0:
            st.missed += 1
        else:
            st.latencies.append(float(seq.t[reach[0]] - seq.t[a]))
    return st


def pool(stats: list[StreamStats]) -> StreamStats:
    """Sum over sequences."""
    total = StreamStats()
    for s in stats:
        total = total.add(s)
    return total


def evaluate(
    model: Any, seqs: list[GestureSequence], light: tuple[int, int] | None = None
) -> dict[str, dict[str, Any]]:
    """``{"raw": summary, "smoothed": summary}`` of a model over sequences (and ``"light"``:
    after a smoother of ``light = (n, k)`` instead of the session's 7/5, when given)."""
    stats: dict[str, list[StreamStats]] = {"raw": [], "smoothed": [], "light": []}
    for seq in seqs:
        raw = stream_outputs(model, seq)
        stats["raw"].append(stream_stats(seq, raw))
        stats["smoothed"].append(stream_stats(seq, smooth(raw, seq.tracked)))
        if light is not None:
            stats["light"].append(stream_stats(seq, smooth(raw, seq.tracked, *light)))
    return {k: pool(v).summary() for k, v in stats.items() if v}
