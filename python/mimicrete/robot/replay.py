"""``mimicrete deploy --replay LOG``: a deploy log's commands replayed in the simulator, to
compare what the simulated arm does with the same commands.

The simulator of the log's task starts with the tile where the log's first tick put it and the
arm at the first tick's joints read; each tick's gated joint target and suction command become
the simulator's action (``clip((command_q - q) / joint_step, -1, 1)``, +-1), one env step a tick.
The replay is written as a demo beside the log (``<log>_replay.mcap``); the summary says how far
the simulated arm ended each tick from the command (rad, the largest joint), how far the read
arm of the log was from the simulated one, and what the task made of it (picked, installed,
fell).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import _native
from mimicrete._native import MimicreteError

from .deploy import STEP_TOPIC, Task


class ReplayError(MimicreteError, ValueError):
    """A log that cannot be replayed (names the file and why)."""


def read_log(path: Path) -> tuple[dict[str, str], list[dict[str, Any]]]:
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            reader = make_reader(f)
            meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            ticks = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=[STEP_TOPIC])]
    except (McapError, ValueError) as e:
        raise ReplayError(f"{path}: not a readable deploy log ({e})") from None
    start = meta.get("episode_start") or meta.get("episode") or {}
    if not ticks or "env_id" not in start:
        raise ReplayError(f"{path}: not a deploy log (no {STEP_TOPIC} ticks or no env_id)")
    return start, ticks


def replay(path: str | Path, out: str | Path | None = None) -> dict[str, Any]:
    path = Path(path)
    start, ticks = read_log(path)
    tile0 = tuple(ticks[0]["tile_pose"])
    task = Task.of_run(start["env_id"], start.get("task_file") or None, tile0)  # type: ignore[arg-type]
    env = task.env
    env.set_joints(np.asarray(ticks[0]["q_read"], np.float64))
    out = Path(out) if out else path.with_name(path.stem + "_replay.mcap")
    meta = {
        "episode": 0,
        "task": task.name,
        "seed": 0,
        "robot_model": start.get("robot_model", "ur3"),
        "control_dt": 0.04,
        "extra": {"replay_of": str(path), "env_id": task.env_id},
    }
    w = _native.DemoWriter(str(out), meta, env=env)
    to_command: list[float] = []
    to_read: list[float] = []
    picked = installed = fell = False
    ended = None
    steps = 0
    obs = env.observation()
    try:
        for k, t in enumerate(ticks):
            snap = env.snapshot()
            q = np.asarray(snap["q"], np.float64)
            if k > 0:
                to_read.append(float(np.abs(np.asarray(t["q_read"]) - q).max()))
            cmd = np.asarray(t["command_q"], np.float64)
            a = np.zeros(env.act_dim, np.float32)
            a[:6] = np.clip((cmd - q) / task.joint_step, -1.0, 1.0)
            a[6] = 1.0 if t["suction"] else -1.0
            obs_next, reward, term, trunc, info = env.step(a)
            after = env.snapshot()
            to_command.append(float(np.abs(np.asarray(after["q"]) - cmd).max()))
            o = after["object"]
            w.write_step(
                k, 0.04 * k, obs, a, float(reward), bool(term), bool(trunc), "",
                after["q"], [*after["tcp"]["t"], *after["tcp"]["q"]], [*o["t"], *o["q"]],
            )  # fmt: skip
            obs = obs_next
            steps += 1
            picked |= bool(info["picked"])
            installed |= bool(info["installed"])
            fell |= bool(info["fell"])
            if term or trunc:
                ended = "installed" if installed else "fell" if fell else "truncated"
                break
        held = bool(env.snapshot()["held"])
        res = {
            "log": str(path),
            "replay": str(out),
            "ticks": len(ticks),
            "replayed": steps,
            "ended": ended,
            "picked": picked,
            "held_at_end": held,
            "installed": installed,
            "fell": fell,
            "sim_to_command_rad": _stats(to_command),
            "read_to_sim_rad": _stats(to_read),
        }
        w.finish(installed, {k: json.dumps(v) for k, v in res.items() if k != "replay"})
    except BaseException:
        w.abandon()
        raise
    return res


def _stats(v: list[float]) -> dict[str, float]:
    if not v:
        return {}
    a = np.asarray(v)
    return {"p50": float(np.median(a)), "max": float(a.max())}


def format_summary(r: dict[str, Any]) -> str:
    c, d = r["sim_to_command_rad"], r["read_to_sim_rad"]
    lines = [
        f"replayed {r['replayed']} of {r['ticks']} ticks of {r['log']} in the simulator"
        + (f" (its episode ended: {r['ended']})" if r["ended"] else ""),
        f"  simulated arm to the command, largest joint: median {c['p50']:.4f} rad, "
        f"max {c['max']:.4f} rad",
    ]
    if d:
        lines.append(
            f"  the log's read arm to the simulated arm: median {d['p50']:.4f} rad, "
            f"max {d['max']:.4f} rad"
        )
    lines.append(
        f"  picked {r['picked']}, held at the end {r['held_at_end']}, installed "
        f"{r['installed']}, fell {r['fell']}"
    )
    lines.append(f"wrote {r['replay']}")
    return "\n".join(lines)
