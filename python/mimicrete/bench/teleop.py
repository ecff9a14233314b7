"""Teleoperation path per hand frame: parse → gesture → hand frame → IK → sim step → record.

Tracking runs at 90 Hz (11.1 ms per frame); the goal is ≤ 1 ms p99 for the whole path. Frames
that run a control step (25 Hz) also pay for IK, the simulator step and the demo record; the
others only for gesture and hand frame. Both are in the per-frame distribution printed.
The log is parsed once up front, as ``mimicrete convert`` does (:func:`mimicrete.hands.parse`,
Rust); each frame is charged its share of that parse (whole-log time / frames) plus reading its
row out of the arrays.
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import demonstrator as sy
from mimicrete import gestures as gest
from mimicrete import tasks
from mimicrete.teleop import convert as cv
from mimicrete.teleop.record import DemoSink, episode_meta
from mimicrete.teleop.session import CONTROL_DT, Session


def _pct(xs: list[float]) -> str:
    a = np.asarray(xs) * 1e6
    if len(a) == 0:
        return "n/a"
    return (
        f"p50 {np.percentile(a, 50):7.1f} µs  p99 {np.percentile(a, 99):7.1f} µs  "
        f"max {a.max():7.1f} µs  (n={len(a)})"
    )


def _native_callee(fn: object) -> str | None:
    """The name of a builtin function or method of ``mimicrete._native`` (None: not one)."""
    owner = getattr(fn, "__self__", None)
    mod = getattr(fn, "__module__", None) or getattr(type(owner), "__module__", None)
    if mod != "mimicrete._native":
        return None
    if owner is not None and not isinstance(owner, type(sys)):
        return f"{type(owner).__name__}.{getattr(fn, '__name__', '?')}"
    return str(getattr(fn, "__name__", "?"))


class CrossingCounter:
    """Counts the calls from Python into ``mimicrete._native`` (a profile hook on C calls; its
    cost makes timings meaningless while it runs, so the timed pass runs without it)."""

    def __init__(self) -> None:
        self.calls: Counter[str] = Counter()

    def _hook(self, frame: object, event: str, arg: object) -> None:
        if event == "c_call":
            name = _native_callee(arg)
            if name is not None:
                self.calls[name] += 1

    def __enter__(self) -> CrossingCounter:
        sys.setprofile(self._hook)
        return self

    def __exit__(self, *exc: object) -> None:
        sys.setprofile(None)


def _recording(
    task: str, log: Any, path: Path, index: int, demo: Path, model: gest.GestureModel
) -> tuple[Session, DemoSink]:
    """A session over hand log ``log`` (read from ``path``) recording into ``demo``, as
    ``mimicrete convert`` makes it."""
    h = log.header
    meta = episode_meta(
        episode=index,
        task_sim=tasks.get(task).sim,
        seed=h["episode_seed"],
        source=str(path),
        model=model,
        layout=h["layout"],
        space=h["space"],
        handedness=h["handedness"],
        extra={},
    )
    sink = DemoSink(demo, meta)
    session = Session(
        task,
        h["layout"],
        h["handedness"],
        cv.calibration_of(log),
        h["episode_seed"],
        model=model,
        recorder=sink,
    )
    return session, sink


def crossings(task: str = "suction") -> tuple[float, float, Counter[str]]:
    """Calls into Rust per hand frame over one synthetic episode converted as ``mimicrete
    convert`` does: (all frames, frames that ran a control step, calls by name)."""
    tmp = Path(tempfile.mkdtemp(prefix="mimicrete-bench-crossings-"))
    path = sy.synth_hands(task, 1, 0, tmp / "logs")[0]
    log = cv.load_log(path)
    model = gest.load_default(tasks.get(task).name)
    session, sink = _recording(task, log, path, 0, tmp / "demo.mcap", model)
    total = Counter[str]()
    per_step: list[int] = []
    per_frame: list[int] = []
    for k in range(len(log)):
        with CrossingCounter() as c:
            steps = session.push(float(log.t[k]), bool(log.tracked[k]), log.joints[k])
        n = sum(c.calls.values())
        per_frame.append(n)
        if steps:
            per_step.append(n)
        total += c.calls
        if session.done:
            break
    session.finish()
    sink.close(session.installed, session.counts)
    return float(np.mean(per_frame)), float(np.mean(per_step)), total


def crossings_live(task: str = "suction", frames: int = 400) -> tuple[float, float]:
    """Calls into Rust per hand frame of the live server's work (``Live.push`` then the state
    the page gets, ``Live.state``), recording, over a synthetic episode's right hand in WebXR
    order: (all frames, frames that ran a control step)."""
    from mimicrete.hands import layouts
    from mimicrete.teleop.live import Live
    from mimicrete.teleop.protocol import WireFrame

    tmp = Path(tempfile.mkdtemp(prefix="mimicrete-bench-crossings-live-"))
    path = sy.synth_hands(task, 1, 0, tmp / "logs", layout="webxr")[0]
    log = cv.load_log(path)
    live = Live(task, tmp / "out", calibration=cv.calibration_of(log))
    live.start()
    per_frame, per_step = [], []
    left = np.zeros((len(layouts.WEBXR_JOINT_NAMES), 3))
    for k in range(min(frames, len(log))):
        f = WireFrame(k, float(log.t[k]), 0.0, bool(log.tracked[k]), False, log.joints[k], left)
        with CrossingCounter() as c:
            steps = live.push(f)
            live.state()
        n = sum(c.calls.values())
        per_frame.append(n)
        if steps:
            per_step.append(n)
    live.discard()
    live.close()
    return float(np.mean(per_frame)), float(np.mean(per_step))


def following(mapping: str, task: str = "suction") -> tuple[float, float, int]:
    """A scripted session per hand orientation a person uses
    (:data:`mimicrete.testing.hand_poses.TURNS`): Start, the right hand held 15 cm above the tool
    turned that way, then moved 7 cm and held. Returns the share of control steps that follow
    the hand (all orientations), the median time from Start to the first step that follows (s,
    hand clock; orientations that never follow left out) and how many never follow."""
    import tempfile as tf

    from mimicrete.teleop.live import Live
    from mimicrete.teleop.view import standing_calibration
    from mimicrete.testing.hand_poses import TURNS, Driver, hand_for_tool

    calib = standing_calibration()
    follow = total = never = 0
    to_follow: list[float] = []
    with tf.TemporaryDirectory(prefix="mimicrete-bench-following-") as tmp:
        for i, turn in enumerate(TURNS):
            live = Live(task, Path(tmp) / str(i), calibration=calib, seed=2, mapping=mapping)
            drive = Driver(live)
            live.start()
            above = drive.tool() + np.array([0.0, 0.0, 0.15])
            here = hand_for_tool(above, turn, calib)
            there = hand_for_tool(above + np.array([0.05, -0.03, -0.04]), turn, calib)
            drive.hold(here, 0.5)
            drive.move(here, there, 0.6)
            drive.hold(there, 1.0)
            live.discard()
            live.close()
            ok = [w is None for w in drive.why]
            follow, total = follow + sum(ok), total + len(ok)
            if any(ok):
                to_follow.append(drive.step_t[ok.index(True)])
            else:
                never += 1
    median = float(np.median(to_follow)) if to_follow else float("nan")
    return follow / max(total, 1), median, never


def run(task: str = "suction", episodes: int = 2) -> None:
    """Print per-frame latency of the teleoperation session exactly as ``mimicrete convert`` runs
    it (:class:`mimicrete.teleop.session.Session` recording into an MCAP demo)."""
    tmp = Path(tempfile.mkdtemp(prefix="mimicrete-bench-teleop-"))
    paths = sy.synth_hands(task, episodes, 0, tmp / "logs")
    spec = tasks.get(task)
    model = gest.load_default(spec.name)
    per_frame: list[float] = []
    per_frame_cpu: list[float] = []
    with_step: list[float] = []
    without_step: list[float] = []
    for i, path in enumerate(paths):
        p0 = time.perf_counter()
        log = cv.load_log(path)
        parse_share = (time.perf_counter() - p0) / len(log)
        session, sink = _recording(task, log, path, i, tmp / "demos" / f"{i}.mcap", model)
        for k in range(len(log)):
            c0 = time.thread_time()
            t0 = time.perf_counter()
            steps = session.push(float(log.t[k]), bool(log.tracked[k]), log.joints[k])
            dt = time.perf_counter() - t0 + parse_share
            per_frame.append(dt)
            per_frame_cpu.append(time.thread_time() - c0 + parse_share)
            (with_step if steps else without_step).append(dt)
            if session.done:
                break
        session.finish()
        sink.close(session.installed, session.counts)
    print(
        f"teleop session per hand frame ({task}, {episodes} synthetic episodes, 90 Hz frames, "
        f"control every {CONTROL_DT * 1000:.0f} ms; the code mimicrete convert and the live "
        "server run):"
    )
    print(f"  whole path  {_pct(per_frame)}   budget 11111 µs (90 Hz), goal p99 <= 1000 µs")
    print(f"  same, CPU time of this thread (excludes waiting for a core): {_pct(per_frame_cpu)}")
    print(f"  frames that ran a control step (IK, sim, record) {_pct(with_step)}")
    print(f"  frames that only updated gesture and target     {_pct(without_step)}")
    all_frames, step_frames, calls = crossings(task)
    print(
        f"  calls from Python into Rust per hand frame: {all_frames:.2f} on average, "
        f"{step_frames:.2f} on frames that ran a control step"
    )
    print("    by function: " + ", ".join(f"{k} {v}" for k, v in calls.most_common()))
    live_all, live_step = crossings_live(task)
    print(
        f"  live server (push + the page's state) per hand frame: {live_all:.2f} calls into Rust "
        f"on average, {live_step:.2f} on frames that ran a control step"
    )
    for mapping in ("clutch", "absolute"):
        share, first, never = following(mapping, task)
        print(
            f"  {mapping:8s} mapping, 10 hand orientations a person uses: {100 * share:5.1f} % of "
            f"steps follow; Start to following {first * 1000:.0f} ms (median), {never}/10 never"
        )
    load = os.getloadavg()[0]
    print(f"  machine load average {load:.2f} on {os.cpu_count()} cores at the end of the run")


if __name__ == "__main__":
    run()
