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
import tempfile
import time
from pathlib import Path

import numpy as np

from mimicrete import gestures as gest
from mimicrete import tasks
from mimicrete.teleop import convert as cv
from mimicrete.teleop import synth as sy
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
        h = log.header
        meta = episode_meta(
            episode=i,
            task_sim=spec.sim,
            seed=h["episode_seed"],
            source=str(path),
            model=model,
            layout=h["layout"],
            space=h["space"],
            handedness=h["handedness"],
            extra={},
        )
        sink = DemoSink(tmp / "demos" / f"{i}.mcap", meta)
        session = Session(
            task,
            h["layout"],
            h["handedness"],
            cv.calibration_of(log),
            h["episode_seed"],
            model=model,
            recorder=sink,
        )
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
    load = os.getloadavg()[0]
    print(f"  machine load average {load:.2f} on {os.cpu_count()} cores at the end of the run")


if __name__ == "__main__":
    run()
