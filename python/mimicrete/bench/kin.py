"""IK benchmark: mc.kin against ikpy (a peer from PyPI) on the same UR3 targets and URDF.

Targets: 10,000 random reachable UR3 poses (q uniform in [-π, π]⁶ → FK). (a) warm start: seed =
true q + N(0, 0.1 rad), the teleoperation case; (b) cold start: no seed. Success = pose error below
1e-6 m and 1e-6 rad for mc.kin; ikpy (scipy least squares, its default) is judged at the looser
1e-4 m / 1e-4 rad. ikpy runs on a subset (it is slow), loading the URDF written by
``mc.kin.urdf("ur3")``. Finally the Rust benchmark binary (``cargo bench -p ur3-kin --bench ik``)
prints the native per-solve figures without Python in the loop.

``python -m mimicrete.bench kin`` (env ``MIMICRETE_BENCH_KIN_N`` and ``MIMICRETE_BENCH_KIN_IKPY_N``
change the counts; ``MIMICRETE_BENCH_KIN_NO_CARGO=1`` skips the Rust binary).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from mimicrete import IkError, kin


def _pose_errors(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position and rotation-angle errors of stacked poses (N, 4, 4)."""
    dp = np.linalg.norm(a[:, :3, 3] - b[:, :3, 3], axis=1)
    r = np.einsum("nji,njk->nik", a[:, :3, :3], b[:, :3, :3])
    c = np.clip((np.trace(r, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    return dp, np.arccos(c)


def _success(q: np.ndarray, ok: np.ndarray, targets: np.ndarray, tol: float) -> np.ndarray:
    good = ok.copy()
    if good.any():
        dp, da = _pose_errors(kin.fk_batch(q[good]), targets[good])
        good[np.flatnonzero(good)] = (dp < tol) & (da < tol)
    return good


def _line(name: str, succ: np.ndarray, times_us: np.ndarray) -> str:
    return (
        f"{name:<44} success {100 * succ.mean():7.3f}% ({succ.sum()}/{succ.size})  "
        f"median {np.median(times_us):9.2f} us  p99 {np.percentile(times_us, 99):9.2f} us"
    )


def _single(targets: np.ndarray, seeds: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    n = len(targets)
    times = np.empty(n)
    q = np.full((n, 6), np.nan)
    ok = np.zeros(n, dtype=bool)
    for i in range(n):
        s = None if seeds is None else seeds[i]
        t0 = time.perf_counter()
        try:
            q[i] = kin.ik(targets[i], seed=s)
            ok[i] = True
        except IkError:
            pass
        times[i] = (time.perf_counter() - t0) * 1e6
    return q, ok, times


def _ikpy_chain(path: str):
    from ikpy.chain import Chain

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        probe = Chain.from_urdf_file(path, base_elements=["base"])
    mask = [link.joint_type == "revolute" for link in probe.links]
    return Chain.from_urdf_file(path, base_elements=["base"], active_links_mask=mask), mask


def _run_ikpy(chain, mask, targets: np.ndarray, seeds: np.ndarray | None):
    active = np.flatnonzero(mask)
    n = len(targets)
    q = np.zeros((n, 6))
    times = np.empty(n)
    for i in range(n):
        init = np.zeros(len(mask))
        if seeds is not None:
            init[active] = seeds[i]
        t0 = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            full = chain.inverse_kinematics_frame(
                targets[i], initial_position=init, orientation_mode="all"
            )
        times[i] = (time.perf_counter() - t0) * 1e6
        q[i] = np.asarray(full)[active]
    return q, times


def _rust_bench() -> None:
    root = Path(__file__).resolve().parents[3]
    cargo = shutil.which("cargo")
    if (
        os.environ.get("MIMICRETE_BENCH_KIN_NO_CARGO")
        or cargo is None
        or not (root / "crates" / "ur3-kin").is_dir()
    ):
        print("\n(Rust benchmark skipped: no cargo or no source tree)")
        return
    print("\n-- Rust, no Python in the loop: cargo bench -p ur3-kin --bench ik --", flush=True)
    r = subprocess.run(
        [cargo, "bench", "-p", "ur3-kin", "--bench", "ik", "--quiet"],
        cwd=root,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    print(r.stdout.rstrip())
    if r.returncode != 0:
        print(f"(cargo bench failed with {r.returncode})\n{r.stderr[-2000:]}")


def run() -> None:
    n = int(os.environ.get("MIMICRETE_BENCH_KIN_N", "10000"))
    n_ikpy = int(os.environ.get("MIMICRETE_BENCH_KIN_IKPY_N", "300"))
    rng = np.random.default_rng(0)
    q_true = rng.uniform(-np.pi, np.pi, (n, 6))
    targets = kin.fk_batch(q_true)
    seeds = q_true + rng.normal(0.0, 0.1, q_true.shape)
    print(
        f"UR3 IK: {n} random reachable targets (q ~ U[-pi,pi]^6 -> FK); warm seed = q + N(0, 0.1)"
    )

    results = {}
    for label, s in (("warm", seeds), ("cold", None)):
        q, ok, times = _single(targets, s)
        succ = _success(q, ok, targets, 1e-6)
        results[label] = (succ, times)
        print(_line(f"mc.kin.ik {label} (one Python call per solve)", succ, times))
    threads = os.cpu_count() or 1
    for label, s in (("warm", seeds), ("cold", None)):
        for th in sorted({1, threads}):
            t0 = time.perf_counter()
            q, ok = kin.ik_batch(targets, s, threads=th)
            dt = time.perf_counter() - t0
            succ = _success(q, ok, targets, 1e-6)
            print(
                f"mc.kin.ik_batch {label}, {th} thread(s){'':<17} success {100 * succ.mean():7.3f}%"
                f"  {n / dt:12.0f} solves/s  ({1e6 * dt / n:.2f} us/solve amortised)"
            )

    try:
        import ikpy  # noqa: F401
    except ImportError:
        print("\nikpy not installed: peer comparison skipped (pip install ikpy)")
        _rust_bench()
        return
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "ur3.urdf")
        Path(path).write_text(kin.urdf("ur3"))
        chain, mask = _ikpy_chain(path)
    sub = slice(0, min(n_ikpy, n))
    print(
        f"\nikpy {ikpy.__version__} (least_squares, orientation_mode='all') on the first {n_ikpy}"
    )
    print("targets, same URDF; its success is judged at 1e-4 m / 1e-4 rad:")
    for label, s in (("warm", seeds[sub]), ("cold", None)):
        q, times = _run_ikpy(chain, mask, targets[sub], s)
        ok = np.ones(len(q), dtype=bool)
        succ = _success(q, ok, targets[sub], 1e-4)
        ours_succ, ours_times = results[label]
        print(_line(f"ikpy {label}", succ, times))
        ours_sub = ours_times[sub]
        print(
            f"{'':<44} mc.kin on the same {len(ours_sub)}: success "
            f"{100 * ours_succ[sub].mean():.3f}%, median {np.median(ours_sub):.2f} us -> "
            f"{np.median(times) / np.median(ours_sub):,.0f}x faster than ikpy (median per call, "
            f"Python to Python)"
        )
    _rust_bench()


if __name__ == "__main__":
    run()
