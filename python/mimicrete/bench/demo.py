"""Demo benchmark: steps written per second and the time to load 60 episodes (200 steps, obs 80)
into arrays, from Rust (the ``demo-log-bench`` binary) and through Python, against a peer: the
official ``mcap`` Python reader plus ``json`` decoding the same files."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

EPISODES, STEPS, OBS, ACT = 60, 200, 80, 7
ROOT = Path(__file__).resolve().parents[3]


def _bench_binary() -> Path:
    exe = ROOT / "target" / "release" / "demo-log-bench"
    subprocess.run(
        ["cargo", "build", "-q", "--release", "-p", "demo-log", "--bin", "demo-log-bench"],
        cwd=ROOT,
        check=True,
    )
    return exe


def _best(f, repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def _peer_load(files: list[Path]) -> tuple[np.ndarray, np.ndarray]:
    """The same arrays through the official mcap reader (CRC checks off, as ours are on) + json."""
    from mcap.reader import make_reader

    obs, act = [], []
    for p in files:
        with p.open("rb") as f:
            for _s, _c, m in make_reader(f).iter_messages(topics=["/demo/step"]):
                d = json.loads(m.data)
                obs.append(d["obs"])
                act.append(d["action"])
    return np.asarray(obs, dtype=np.float32), np.asarray(act, dtype=np.float32)


def _python_write(dirpath: Path, episodes: int) -> float:
    import mimicrete as mc

    q = [0.1, -1.2, 1.0, -0.5, -1.57, 0.0]
    pose = [-0.3, 0.1, 0.2, 0.0, 0.0, 0.0, 1.0]
    hand = np.zeros((26, 3))
    rng = np.random.default_rng(0)
    obs = rng.standard_normal((STEPS, OBS)).astype(np.float32)
    act = rng.standard_normal((STEPS, ACT)).astype(np.float32)
    meta = {
        "task": "suction",
        "hand": {"layout": "openxr", "space": "openxr", "handedness": "right"},
    }
    t0 = time.perf_counter()
    for e in range(episodes):
        with mc.demos.DemoWriter(str(dirpath / f"py_{e:03d}.mcap"), {**meta, "episode": e}) as w:
            for i in range(STEPS):
                t = mc.tasks.CONTROL_DT * i
                w.write_hand_frame(t, hand, True)
                last = i == STEPS - 1
                w.write_step(i, t, obs[i], act[i], float(last), last, False, "hold", q, pose, pose)
            w.finish(True)
    return time.perf_counter() - t0


def run() -> None:
    import mimicrete as mc

    if not hasattr(mc._native, "demo_load"):
        print("demo: mimicrete._native was built without demo-log; nothing to measure")
        return
    tmp = Path(tempfile.mkdtemp(prefix="mimicrete-bench-demo-"))
    try:
        data = tmp / "demos"
        exe = _bench_binary()
        out = (
            subprocess.run(
                [
                    str(exe),
                    "--dir",
                    str(data),
                    "--keep",
                    "--episodes",
                    str(EPISODES),
                    "--steps",
                    str(STEPS),
                    "--obs",
                    str(OBS),
                    "--act",
                    str(ACT),
                ],
                capture_output=True,
                text=True,
                check=True,
            )
            .stdout.strip()
            .splitlines()
        )
        r = json.loads(out[-1])
        mb = r["bytes"] / 1e6
        print(
            f"  Rust write: {r['steps']} steps (5 channels) in {r['write_s']:.3f} s = "
            f"{r['steps_per_s']:,.0f} steps/s ({mb:.1f} MB on disk)"
        )
        print(
            f"  Rust load:  {EPISODES} episodes x {STEPS} steps x obs {OBS} -> arrays in "
            f"{r['load_s'] * 1e3:.1f} ms (best of 3)"
        )

        py_eps = 10
        py_dir = tmp / "py"
        py_dir.mkdir()
        t_py = _python_write(py_dir, py_eps)
        print(
            f"  Python DemoWriter: {py_eps * STEPS / t_py:,.0f} steps/s "
            f"({py_eps} episodes x {STEPS} steps incl. hand frames)"
        )

        d = mc.demos.load(data)
        assert d.obs.shape == (EPISODES * STEPS, OBS)
        t_load = _best(lambda: mc.demos.load(data))
        files = sorted(data.glob("*.mcap"))
        t_peer = _best(lambda: _peer_load(files), repeat=1)
        p_obs, p_act = _peer_load(files)
        assert np.array_equal(p_obs, d.obs) and np.array_equal(p_act, d.actions)
        print(
            f"  Python mc.demos.load: {t_load * 1e3:.1f} ms (best of 3); peer (official mcap "
            f"reader + json): {t_peer * 1e3:.1f} ms -> {t_peer / t_load:.1f}x faster"
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    run()
