"""``mimicrete deploy``: a trained policy at 25 Hz on a robot, every command gated and every tick
logged as a demo.

One tick: read the robot (the latency clock starts when the read returns) -> check the state
(:meth:`Gates.check_state`: connection, safety mode, stalled stream, joint jump) -> where the tile
is -> the observation the policy was trained on (:mod:`.observe`) -> the policy's action -> the
joint target ``q_read + action[:6] * joint_step`` and the suction command latched from
``action[6]`` (as the simulator reads an action) -> the gates (:meth:`Gates.gate_command`) -> the
command handed to the robot (in shadow mode: to nobody) -> the latency checked against the
deadline (2 control periods) -> the tick logged.

Any stop (a fault the gates found, a missed deadline, the policy raising, Ctrl-C, SIGTERM, the
requested number of ticks, the simulated episode ending) stops the arm (``stop``: servoStop, then
stopScript on a controller) and finishes the log, which names the reason; the log is a valid MCAP
demo whatever ended the run.
"""

from __future__ import annotations

import contextlib
import json
import signal
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import _native

from . import RobotError
from .gates import Gates, Limits, Stop
from .observe import Observer

#: the policy's control period (s): 25 Hz, the simulator's CONTROL_DT
PERIOD = 0.04
STEP_TOPIC = "/deploy/tick"


@dataclass
class Outcome:
    """How a deployment ended."""

    path: Path
    ticks: int
    reason: str
    #: ``ticks`` (ran what was asked), ``episode`` (the simulated episode ended), ``signal``
    #: (Ctrl-C, SIGTERM), or the kind of the :class:`Stop`: safety_mode, connection, stalled,
    #: joint_jump, deadline, policy, tile_pose, robot (the robot's interface raised)
    kind: str
    gate_counts: dict[str, int] = field(default_factory=dict)
    latency_ms: dict[str, float] = field(default_factory=dict)

    @property
    def fault(self) -> bool:
        return self.kind not in ("ticks", "episode", "signal")


@dataclass
class Task:
    """What deploy needs of the run's task: its spec, joint step, the target's centre at the
    tile's pose, and the SimEnv reset there (the log's scene)."""

    name: str
    spec: dict[str, Any]
    joint_step: float
    env: Any
    task_file: str | None
    env_id: str = "TileSuction-v0"

    @classmethod
    def of_run(cls, env_id: str, task_file: str | None, tile: tuple[float, float, float]) -> Task:
        from mimicrete import tasks

        if task_file is not None:
            env = _native.SimEnv.from_spec_file(task_file, 0)
        else:
            env = _native.SimEnv(tasks.get(env_id).sim, 0)
        env.reset(0, object_pose=list(tile), target_offset=[0.0, 0.0])
        spec = env.spec()
        return cls(spec["name"], spec, float(env.joint_step), env, task_file, env_id)


def torch_policy(actor: Any) -> Callable[[np.ndarray], np.ndarray]:
    """The deterministic policy of a trained actor as obs (D,) -> action (act_dim,)."""
    import torch

    def act(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            a = actor.deterministic(torch.from_numpy(np.asarray(obs, np.float32))[None])
        return a[0].numpy().astype(np.float64)

    return act


class DeployLog:
    """The run's MCAP demo: ``/demo/step`` per tick (the observation, the command after the gates
    as an action, the joints and TCP read, the tile), ``/events`` (``gate:<name>`` when a gate
    fired, ``stop``), ``/deploy/tick`` (``mimicrete.DeployTick.v1``: everything else)."""

    def __init__(self, path: Path, meta: dict[str, Any], env: Any) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.path = path
        self.w = _native.DemoWriter(str(path), meta, env=env)
        self.latencies: list[float] = []
        self.t = 0.0

    def tick(
        self,
        step: int,
        t: float,
        obs: np.ndarray,
        action: np.ndarray,
        ee: np.ndarray,
        tile_xyz: np.ndarray,
        tile_yaw: float,
        rec: dict[str, Any],
    ) -> None:
        self.t = t
        half = tile_yaw / 2
        tile = [*(float(x) for x in tile_xyz), 0.0, 0.0, float(np.sin(half)), float(np.cos(half))]
        self.w.write_step(
            step,
            t,
            obs.astype(np.float32),
            action.astype(np.float32),
            0.0,
            False,
            False,
            "",
            rec["q_read"],
            ee,
            tile,
            events=[f"gate:{g}" for g in rec["gates"]],
        )
        self.w.write_deploy_tick(rec)
        self.latencies.append(rec["latency_ms"])

    def finish(self, outcome: Outcome) -> None:
        self.w.write_event(self.t, "stop", {"reason": outcome.reason, "kind": outcome.kind})
        extra = {
            "stop_reason": outcome.reason,
            "stop_kind": outcome.kind,
            "gate_counts": outcome.gate_counts,
            "latency_ms": outcome.latency_ms,
        }
        self.w.finish(False, {k: json.dumps(v) for k, v in extra.items()})


def latency_stats(ms: list[float]) -> dict[str, float]:
    if not ms:
        return {}
    v = np.asarray(ms)
    return {
        "n": float(len(v)),
        "p50": float(np.percentile(v, 50)),
        "p99": float(np.percentile(v, 99)),
        "max": float(v.max()),
    }


#: what the loop's stop says for each signal that asks it to stop
SIGNAL_REASONS = {signal.SIGINT: "interrupted (Ctrl-C)", signal.SIGTERM: "SIGTERM received"}


@contextlib.contextmanager
def _signals_ask_to_stop() -> Iterator[list[str]]:
    """While the loop runs (main thread; then restored), SIGINT and SIGTERM only ask it to stop:
    the handler notes the signal's reason in the list it yields, and the loop stops at its next
    tick. An exception raised from the handler would surface wherever the loop happened to be,
    inside the policy's call it read as a policy fault (seen: "policy error: Stop: SIGTERM
    received", exit 1)."""
    asked: list[str] = []
    if threading.current_thread() is not threading.main_thread():
        yield asked
        return

    def handler(signum: int, frame: object) -> None:
        asked.append(SIGNAL_REASONS[signal.Signals(signum)])

    old = {sig: signal.signal(sig, handler) for sig in SIGNAL_REASONS}
    try:
        yield asked
    finally:
        for sig, h in old.items():
            signal.signal(sig, h)


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM ignored while the arm is stopped and the log closed (main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def run(
    robot: Any,
    policy: Callable[[np.ndarray], np.ndarray],
    task: Task,
    tile_source: Any,
    out: Path,
    *,
    limits: Limits,
    ticks: int | None = None,
    realtime: bool = True,
    meta_extra: dict[str, Any] | None = None,
    on_tick: Callable[[int], None] | None = None,
) -> Outcome:
    """Run ``policy`` on ``robot`` until a stop; the log is written to ``out`` (a file path).
    The start gate runs before anything is written (:class:`~.gates.StartRefused` propagates)."""
    gates = Gates(limits)
    first = robot.read()
    gates.check_start(first)
    target = np.asarray(task.env.snapshot()["target"]["t"], np.float64)
    observer = Observer(task.spec, target)
    meta = {
        "episode": 0,
        "task": task.name,
        "seed": 0,
        "robot_model": limits.model,
        "control_dt": limits.period,
        "extra": {
            "deploy_backend": robot.backend,
            "tile_source": tile_source.label,
            "speed_cap": limits.speed_cap,
            "joint_step": limits.joint_step,
            "env_id": task.env_id,
            "task_file": task.task_file or "",
            **(meta_extra or {}),
        },
    }
    log = DeployLog(out, meta, task.env)
    suction = False
    step = 0
    reason, kind = "", ""
    t0 = time.monotonic()
    last_cmd_at: float | None = None
    src: tuple[float, float, float] | None = None
    try:
        with _signals_ask_to_stop() as asked:
            while True:
                if asked:
                    raise Stop(asked[0], "signal")
                if ticks is not None and step >= ticks:
                    reason, kind = f"ran the {ticks} ticks asked for", "ticks"
                    break
                ended = getattr(robot, "ended", None)
                if ended is not None:
                    reason, kind = f"the simulated episode ended: {ended}", "episode"
                    break
                if getattr(robot, "deadline_missed", False):
                    raise Stop(
                        "deadline: the servo stream had no new target for 2 control periods",
                        "deadline",
                    )
                try:
                    state = robot.read()
                except (RuntimeError, RobotError) as e:  # ur-rtde's errors, the servo stream's
                    raise Stop(f"robot error while reading: {e}", "robot") from None
                if last_cmd_at is not None and state.read_at - last_cmd_at > limits.deadline:
                    raise Stop(
                        f"deadline: {1000 * (state.read_at - last_cmd_at):.0f} ms since the last "
                        f"command (at most {1000 * limits.deadline:.0f})",
                        "deadline",
                    )
                gates.check_state(state)
                if not observer.held or src is None:  # a held tile: the cups hide it
                    try:
                        src = tile_source.pose()
                    except ValueError as e:
                        raise Stop(f"tile pose: {e}", "tile_pose") from None
                T = observer.tool0(state.q)
                tile_xyz, how = observer.tile_centre(T, suction, src, tile_source.version)
                obs = observer.push(state.q, suction, tile_xyz, T)
                try:
                    raw = np.asarray(policy(obs), np.float64)
                except Exception as e:  # noqa: BLE001 (any policy failure stops the arm)
                    raise Stop(f"policy error: {type(e).__name__}: {e}", "policy") from None
                if raw.shape != (7,):
                    raise Stop(
                        f"policy error: action of shape {raw.shape}, expected (7,)", "policy"
                    )
                cmd = raw[6]
                if np.isfinite(cmd):
                    suction = True if cmd >= 0.5 else False if cmd <= -0.5 else suction
                q_cmd, fired = gates.gate_command(state.q, state.q + raw[:6] * limits.joint_step)
                try:
                    robot.send_joint_target(q_cmd, suction)
                except (RuntimeError, RobotError) as e:
                    raise Stop(f"robot error while commanding: {e}", "robot") from None
                now = time.monotonic()
                latency = now - state.read_at
                last_cmd_at = now
                tcp_T = T.copy()
                tcp_T[:3, 3] = T[:3, 3] + T[:3, 2] * limits.tcp_z
                action = np.concatenate(
                    [
                        (q_cmd - state.q) / limits.joint_step,
                        [1.0 if suction else -1.0] if np.isfinite(cmd) else [0.0],
                    ]
                )
                source = tile_source.label if how == "source" else how
                rec = {
                    "step": step,
                    "t": now - t0,
                    "robot_time": state.robot_time,
                    "q_read": [float(x) for x in state.q],
                    "tcp_read": [float(x) for x in state.tcp],
                    "safety_mode": state.safety_mode,
                    "digital_out": state.digital_out,
                    "tile_pose": [float(tile_xyz[0]), float(tile_xyz[1]), float(src[2])],
                    "tile_source": source,
                    "raw_action": [float(x) if np.isfinite(x) else None for x in raw],
                    "command_q": [float(x) for x in q_cmd],
                    "suction": bool(suction),
                    "gates": fired,
                    "sent": bool(robot.sends),
                    "latency_ms": 1000.0 * latency,
                }
                log.tick(step, now - t0, obs, action, tcp_T, tile_xyz, src[2], rec)
                step += 1
                if on_tick is not None:
                    on_tick(step)
                if latency > limits.deadline:
                    raise Stop(
                        f"deadline: {1000 * latency:.0f} ms from the read to the command (at most "
                        f"{1000 * limits.deadline:.0f})",
                        "deadline",
                    )
                if realtime:
                    delay = t0 + step * limits.period - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)
    except Stop as s:
        reason, kind = s.reason, s.kind
    except KeyboardInterrupt:  # a Ctrl-C in the instant before the loop's handler is in place
        reason, kind = SIGNAL_REASONS[signal.SIGINT], "signal"
    finally:
        if not reason:  # an exception of our own: still stop and close, then let it through
            reason, kind = "internal error", "error"
        with _signals_held():  # a second Ctrl-C must not cut the stop or the log short
            robot.stop(reason)
            outcome = Outcome(
                out, step, reason, kind, dict(gates.counts), latency_stats(log.latencies)
            )
            log.finish(outcome)
            robot.close()
            tile_source.close()
    return outcome


def summary(path: str | Path) -> dict[str, Any] | None:
    """The ``/deploy/tick`` records of a deploy log summarised (None: not a deploy log): ticks,
    commands sent, each gate's count, the tile sources, the latency percentiles (ms), the stop
    reason (from the ``episode`` metadata; None in a cut file)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        reader = make_reader(f)
        summ = reader.get_summary()
        if summ is None or not any(c.topic == STEP_TOPIC for c in summ.channels.values()):
            return None
        recs = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=[STEP_TOPIC])]
        episode = {m.name: dict(m.metadata) for m in reader.iter_metadata()}.get("episode", {})
    gates: dict[str, int] = {}
    sources: dict[str, int] = {}
    for r in recs:
        for g in r["gates"]:
            gates[g] = gates.get(g, 0) + 1
        sources[r["tile_source"]] = sources.get(r["tile_source"], 0) + 1
    lat = latency_stats([r["latency_ms"] for r in recs])
    return {
        "ticks": len(recs),
        "sent": sum(1 for r in recs if r["sent"]),
        "gated_ticks": sum(1 for r in recs if r["gates"]),
        "gates": gates,
        "tile_sources": sources,
        "latency_ms": lat,
        "stop_reason": json.loads(episode["stop_reason"]) if "stop_reason" in episode else None,
        "stop_kind": json.loads(episode["stop_kind"]) if "stop_kind" in episode else None,
    }
