"""Simulator throughput: the Rust ``VecEnv`` against gymnasium's MuJoCo ``Pusher-v5``.

1. The Rust bench binary (``cargo bench -p tile-sim --bench vecenv``): VecEnv(64), uniform random
   actions, 1 and 2 threads, env-steps/s including FK, physics, observation stacking and
   auto-resets, no Python in the loop. Goal: >= 300k env-steps/s on 2 cores.
   Then TileSuction per arm model (ur3, ur3e, ur5e, ur10e; the family specs in
   ``crates/tile-sim/tasks/``), 2 threads, each beside the UR3 as a ratio.
2. Through Python: ``mimicrete.envs.make_vec("TileSuction-v0", 64)`` (numpy in/out, the gymnasium
   VectorEnv wrapper, GIL released while the worlds step) beside ``Pusher-v5`` as a 16-env
   ``SyncVectorEnv`` (a 7-DoF MuJoCo arm pushing an object) in the same run, alternating rounds so
   both see the same machine load; prints the ratio (goal >= 15x).

``python -m mimicrete.bench sim``; env ``MIMICRETE_BENCH_SIM_SECONDS`` (default 3) sets the time per
measurement, ``MIMICRETE_BENCH_SIM_NO_CARGO=1`` skips the Rust binary. Needs ``mujoco`` and
``imageio`` for the peer (the peer is skipped with a note when they are missing).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import time
import warnings
from pathlib import Path

import numpy as np


def _repo_root() -> Path:
    return Path(__file__).resolve().parents[3]


def _rust_bench(seconds: float) -> None:
    if os.environ.get("MIMICRETE_BENCH_SIM_NO_CARGO") == "1" or shutil.which("cargo") is None:
        print("Rust VecEnv bench: skipped (no cargo or MIMICRETE_BENCH_SIM_NO_CARGO=1)")
        return
    cmd = ["cargo", "bench", "-q", "-p", "tile-sim", "--bench", "vecenv", "--", "64", str(seconds)]
    print("$ " + " ".join(cmd), flush=True)
    res = subprocess.run(cmd, cwd=_repo_root(), capture_output=True, text=True, check=False)
    for line in res.stdout.splitlines():
        if line.strip():
            print("   " + line)
    if res.returncode != 0:
        print("   (cargo bench failed)\n" + res.stderr[-2000:])


def _rate(step, actions: list[np.ndarray], n_envs: int, seconds: float) -> float:
    k = 0
    t0 = time.perf_counter()
    while True:
        for a in actions:
            step(a)
        k += len(actions)
        dt = time.perf_counter() - t0
        if dt >= seconds:
            return k * n_envs / dt


def _ours(threads: int, seconds: float) -> float:
    from mimicrete import envs

    n = 64
    venv = envs.make_vec("TileSuction-v0", n, seed=0, num_threads=threads)
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    acts = [rng.uniform(-1, 1, (n, 7)).astype(np.float32) for _ in range(64)]
    for a in acts[:8]:
        venv.step(a)
    return _rate(venv.step, acts, n, seconds)


def _pusher(seconds: float) -> float | None:
    import gymnasium as gym

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            venv = gym.make_vec("Pusher-v5", num_envs=16, vectorization_mode="sync")
    except Exception as e:  # mujoco/imageio missing
        print(f"Pusher-v5 peer unavailable: {type(e).__name__}: {e}")
        return None
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    shape = venv.action_space.shape
    acts = [rng.uniform(-2, 2, shape).astype(np.float32) for _ in range(64)]
    for a in acts[:8]:
        venv.step(a)
    r = _rate(venv.step, acts, 16, seconds)
    venv.close()
    return r


def _call_overhead(seconds: float) -> None:
    """Cost of crossing into Rust per batched call: a raw ``_native.SimVecEnv(1).step`` (one env's
    physics plus conversion), the same through the gymnasium wrapper, and the Rust-side step of that
    one env timed inside the same loop by stepping VecEnv(64) and dividing, so the difference is
    the binding's share."""
    from mimicrete import _native, envs

    act1 = np.zeros((1, 7), np.float32)
    raw = _native.SimVecEnv("TileSuction", 1, 0, 1)
    raw.reset(0)
    wrapped = envs.make_vec("TileSuction-v0", 1, seed=0, num_threads=1)
    wrapped.reset(seed=0)
    big = _native.SimVecEnv("TileSuction", 64, 0, 1)
    big.reset(0)
    act64 = np.zeros((64, 7), np.float32)

    def per_call(fn, a) -> float:
        k, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds / 3:
            for _ in range(100):
                fn(a)
            k += 100
        return (time.perf_counter() - t0) / k * 1e6

    raw_us = per_call(raw.step, act1)
    wrap_us = per_call(wrapped.step, act1)
    per_env_us = per_call(big.step, act64) / 64
    print("Per batched call (µs), one env, zero actions:")
    print(f"   raw _native.SimVecEnv.step          : {raw_us:8.1f}")
    print(f"   gymnasium VectorEnv wrapper         : {wrap_us:8.1f}")
    print(f"   one env-step inside VecEnv(64)/64   : {per_env_us:8.1f}")
    print(
        f"   binding overhead per call (raw - one env-step): {raw_us - per_env_us:6.1f} µs;"
        f" wrapper adds {wrap_us - raw_us:.1f} µs"
    )


def run() -> None:
    seconds = float(os.environ.get("MIMICRETE_BENCH_SIM_SECONDS", "3"))
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    _rust_bench(seconds)
    try:
        import mujoco

        peer_name = f"gymnasium Pusher-v5 SyncVectorEnv(16), mujoco {mujoco.__version__}"
    except ImportError:
        peer_name = "Pusher-v5 (mujoco missing)"
    ours1, ours2, peer = [], [], []
    for _ in range(2):
        ours1.append(_ours(1, seconds))
        ours2.append(_ours(2, seconds))
        p = _pusher(seconds)
        if p is not None:
            peer.append(p)
    o1, o2 = float(np.median(ours1)), float(np.median(ours2))
    print(
        "Through Python (numpy in/out, gymnasium VectorEnv API), env-steps/s, median of 2 rounds:"
    )
    print(f"   mimicrete TileSuction VecEnv(64), 1 thread : {o1:>10.0f}")
    print(f"   mimicrete TileSuction VecEnv(64), 2 threads: {o2:>10.0f}")
    if peer:
        pm = float(np.median(peer))
        print(f"   {peer_name}: {pm:>10.0f}")
        print(f"   ratio (ours, 2 threads / Pusher-v5 sync16): {o2 / pm:.1f}x   (goal >= 15x)")
    _call_overhead(seconds)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
