"""Teleoperation path per hand frame: parse → gesture → hand frame → IK → sim step → record.

Tracking runs at 90 Hz (11.1 ms per frame); the goal is ≤ 1 ms p99 for the whole path. Frames
that fall on a control tick (25 Hz) also pay for IK, the simulator step and the demo record; the
others only for parse, gesture and hand frame. Both are in the per-frame distribution printed.
The log is parsed once up front, as ``mimicrete convert`` does (:func:`mimicrete.handlog.parse`,
Rust); each frame is charged its share of that parse (whole-log time / frames) plus reading its
row out of the arrays.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

import numpy as np

from mimicrete import convert as cv
from mimicrete import synth as sy


def _pct(xs: list[float]) -> str:
    a = np.asarray(xs) * 1e6
    if len(a) == 0:
        return "n/a"
    return (
        f"p50 {np.percentile(a, 50):7.1f} µs  p99 {np.percentile(a, 99):7.1f} µs  "
        f"max {a.max():7.1f} µs  (n={len(a)})"
    )


def run(task: str = "suction", episodes: int = 2) -> None:
    """Print per-frame latency of the whole teleoperation path."""
    have_sim = sy.have_simulator()
    tmp = Path(tempfile.mkdtemp(prefix="mimicrete-bench-teleop-"))
    if have_sim:
        backend = cv.Backend()
        scene_fn = sy.scene_from_env
    else:
        backend = None

        def scene_fn(task: str, seed: int) -> sy.Scene:
            return sy.Scene(
                task,
                seed,
                np.array([0.0, 0.25, 0.2]),
                0.05,
                np.array([0.08, 0.32, 0.005]),
                np.array([-0.22, 0.28, 0.045]),
            )

    paths = sy.synth_hands(task, episodes, 0, tmp / "logs", scene_fn=scene_fn)
    per_frame: list[float] = []
    per_frame_cpu: list[float] = []
    stages: dict[str, list[float]] = {
        "parse": [],
        "gesture+frame": [],
        "ik": [],
        "sim step": [],
        "record": [],
    }
    for i, path in enumerate(paths):
        p0 = time.perf_counter()
        log = cv.load_log(path)
        parse_share = (time.perf_counter() - p0) / len(log)
        header = log.header
        calib = cv.calibration_of(log)
        if backend is not None:
            tele = cv.Teleop(
                task,
                header["layout"],
                header["handedness"],
                calib,
                hand_to_target=backend.hand_to_target_for(calib),
            )
            env = backend.make_env(task)
            obs, _ = env.reset(seed=header["episode_seed"])
            fd = backend.obs_frame_dim(task)
            q = np.asarray(obs[-fd:][:6], dtype=np.float64)
            q_ik = q.copy()
            dt, max_step = backend.control_dt, backend.max_joint_step
            writer = backend.open_writer(
                tmp / "demos" / f"{i}.mcap",
                task,
                header["episode_seed"],
                i,
                log,
                tele.model,
                str(path),
            )
        else:
            tele = cv.Teleop(task, header["layout"], header["handedness"], calib)
            dt, max_step, env, writer = 0.04, 0.04, None, None
        t_first = None
        step = 0
        done = False
        for k in range(len(log)):
            c0 = time.thread_time()
            t0 = time.perf_counter()
            t, tracked, arr = float(log.t[k]), bool(log.tracked[k]), log.joints[k]
            t1 = time.perf_counter()
            tele.push(t, tracked, arr)
            t2 = time.perf_counter()
            t0 -= parse_share
            c0 -= parse_share
            stages["parse"].append(t1 - t0)
            stages["gesture+frame"].append(t2 - t1)
            t_first = t if t_first is None else t_first
            if writer is not None:  # the raw hand frame goes into the demo too
                writer.hand(t - t_first, arr, tracked, t)
                t2b = time.perf_counter()
                stages["record"].append(t2b - t2)
                t2 = t2b
            if (
                env is not None
                and not done
                and t >= t_first + step * dt
                and tele.target is not None
            ):
                try:
                    sol = backend.ik(tele.target, q_ik)
                    q_ik = q_ik + cv.wrap_to_pi(sol - q_ik)
                except ArithmeticError:
                    pass
                t3 = time.perf_counter()
                a = np.zeros(8 if task == "screw" else 7, dtype=np.float32)
                a[:6] = cv.joint_action(q_ik, q, max_step)
                a[6] = tele.command()[0]
                obs, r, term, trunc, _ = env.step(a)
                q = np.asarray(obs[-fd:][:6], dtype=np.float64)
                t4 = time.perf_counter()
                writer.step(
                    step,
                    t - t_first,
                    obs,
                    a,
                    float(r),
                    bool(term),
                    bool(trunc),
                    tele.smoother.state or "",
                    env.snapshot(),
                    [],
                )
                t5 = time.perf_counter()
                stages["ik"].append(t3 - t2)
                stages["sim step"].append(t4 - t3)
                stages["record"].append(t5 - t4)
                step += 1
                done = bool(term or trunc)
                per_frame.append(t5 - t0)
                per_frame_cpu.append(time.thread_time() - c0)
            else:
                per_frame.append(t2 - t0)
                per_frame_cpu.append(time.thread_time() - c0)
        if writer is not None:
            writer.close(done, tele.counts)
    print(
        f"teleop path per hand frame ({task}, {episodes} synthetic episodes, 90 Hz frames, "
        f"control every {dt * 1000:.0f} ms):"
    )
    print(f"  whole path  {_pct(per_frame)}   budget 11111 µs (90 Hz), goal p99 <= 1000 µs")
    print(f"  same, CPU time of this thread (excludes waiting for a core): {_pct(per_frame_cpu)}")
    for name, xs in stages.items():
        print(f"  {name:13s} {_pct(xs)}")
    load = os.getloadavg()[0]
    print(f"  machine load average {load:.2f} on {os.cpu_count()} cores at the end of the run")
    if env is None:
        print(
            "  NOTE: partial: IK, sim step and record need mimicrete.envs / kin / demos "
            "(simulator bindings), not available in this build"
        )


if __name__ == "__main__":
    run()
