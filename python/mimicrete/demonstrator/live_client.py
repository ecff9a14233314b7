"""Demonstrations recorded through the live path, without a headset: the scripted person's plan
performed with hand shapes captured on a real Quest, sent to a real ``mimicrete teleop`` server
over its WebSocket protocol (docs/formats.md §3) as the page sends them.

What differs from ``synth-hands`` + ``convert`` (the same plan, :func:`mimicrete.demonstrator.
synth_episode`):

* the hand is one of IWER's Quest-captured shapes (:mod:`mimicrete.gestures.captured`) for the
  class the person shows (pinch for ``closing``, relaxed for ``opening``, point for ``fixed``; the
  screw classes spliced from captured fingers), placed so that its hand frame is the planned one,
  blended between shapes while a gesture changes, with Quest-like tracking noise;
* frames come at the Quest's 72 Hz with ±1.5 ms of jitter, in real time, and the person pauses
  (holds still 0.3–0.8 s) before grasping and before letting go;
* the server reads the hand with its gesture model and drives with its mapping (the clutch by
  default: Start engages on the first frame), records the demo and the hand log, and gets the
  page's acknowledgements, so the demo carries its stage times.
"""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete.gestures import captured as cap
from mimicrete.hands.layouts import FRAME_JOINTS
from mimicrete.hands.model import hand_frame
from mimicrete.kin import Calibration
from mimicrete.teleop.protocol import pack_frame

from . import SynthEpisode, synth_episode
from .scene import hand_pose_for_tool0, scene_from_env

QUEST_HZ = 72.0
JITTER_S = 0.0015
#: The shape IWER captured for each suction / gripping class.
_GRIP_POSE = {cls: pose for pose, cls in cap.IWER_GRIP_CLASS.items()}


def captured_shape(cls: str) -> np.ndarray:
    """A right hand (25, 3) of class ``cls`` from IWER's captured poses, in its own hand frame
    (:func:`mimicrete.hands.model.hand_frame`: the wrist at the origin)."""
    if cls in cap.SCREW_SPLICES:
        palm, fingers = cap.SCREW_SPLICES[cls]
        j = cap.splice(palm, fingers, "right")
    else:
        j = cap.iwer_pose(_GRIP_POSE[cls], "right")
    w, i, m = FRAME_JOINTS["webxr"]
    rot, origin = hand_frame(j[w], j[i], j[m])
    return (j - origin) @ rot


def quest_take(ep: SynthEpisode, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The episode's plan performed with captured shapes at Quest rate: times (n,) and right-hand
    WebXR joints (n, 25, 3) in the episode's headset space."""
    calib = Calibration.from_dict(ep.header["extra"]["calibration"])
    rot, wrist = hand_pose_for_tool0(ep.tool0, "right", calib)
    shapes = {g: captured_shape(g) for g in set(ep.gestures)}
    # the plan's frame shown at each Quest frame ...
    plan_dt = float(ep.t[1] - ep.t[0])
    idx = list(
        np.minimum(np.round(np.arange(0.0, ep.t[-1], 1.0 / QUEST_HZ) / plan_dt), len(ep.t) - 1)
    )
    idx = [int(k) for k in idx]
    # ... and a pause (the hand held still) before each change of gesture: grasp, let go
    changes = [k for k in range(1, len(ep.gestures)) if ep.gestures[k] != ep.gestures[k - 1]]
    for c in reversed(changes):
        i = next((i for i, k in enumerate(idx) if k >= c), None)
        if i is not None and i > 0:
            idx[i:i] = [idx[i - 1]] * int(rng.uniform(0.3, 0.8) * QUEST_HZ)
    n = len(idx)
    dt = 1.0 / QUEST_HZ + rng.uniform(-JITTER_S, JITTER_S, size=n)
    t = np.concatenate([[0.0], np.cumsum(dt[1:])])
    joints = np.empty((n, 25, 3))
    for i, k in enumerate(idx):
        world = _blended(ep, shapes, k) @ rot[k].T + wrist[k]
        joints[i] = cap.quest_noise(world, rng)
    return t, joints


def _blended(ep: SynthEpisode, shapes: dict[str, np.ndarray], k: int) -> np.ndarray:
    """The shape at plan frame ``k``: a change of gesture blends the two captured shapes over its
    in-between frames (``ep.changing``)."""
    if not ep.changing[k]:
        return shapes[ep.gestures[k]]
    a = k
    while a > 0 and ep.changing[a - 1]:
        a -= 1
    b = k
    while b + 1 < len(ep.changing) and ep.changing[b + 1]:
        b += 1
    before = ep.gestures[max(a - 1, 0)]
    after = ep.gestures[min(b + 1, len(ep.gestures) - 1)]
    u = (k - a + 1) / (b - a + 2)
    return (1 - u) * shapes[before] + u * shapes[after]


async def _drive(
    url: str, takes: list[tuple[np.ndarray, np.ndarray]], progress: bool
) -> list[dict[str, Any]]:
    """Play the takes as the page would: hello, then per take Start, the frames in real time
    (each answered by a state, acknowledged in batches of 16) until the episode ends (or Stop
    after the last frame), and the server's ``saved`` message."""
    import aiohttp
    from tqdm import tqdm

    saved: list[dict[str, Any]] = []

    async def receive(ws: Any, until: Any) -> dict[str, Any]:
        """Messages until one ``until(msg)`` accepts; the ``saved`` ones are kept on the way."""
        while True:
            msg = await ws.receive_json(timeout=60)
            if msg["type"] == "episode" and msg["event"] == "saved":
                saved.append(msg)
            if until(msg):
                return msg

    seq = 0
    bar = tqdm(total=len(takes), desc="through teleop", unit="ep", disable=not progress)
    async with aiohttp.ClientSession() as http, http.ws_connect(url) as ws:
        hello = {"type": "hello", "protocol": 1, "role": "driver", "client": "live-client"}
        await ws.send_json(hello)
        await receive(ws, lambda m: m["type"] == "hello")
        loop = asyncio.get_running_loop()
        for n, (t, joints) in enumerate(takes, start=1):
            await ws.send_json({"type": "control", "action": "start"})
            t0, acks = loop.time(), []
            recording = True
            for i in range(len(t)):
                await asyncio.sleep(max(0.0, t0 + t[i] - loop.time()))
                await ws.send_bytes(pack_frame(seq, float(t[i]), loop.time() * 1000.0, joints[i]))
                state = await receive(ws, lambda m: m["type"] == "state")
                seq += 1
                acks.append([state["seq"], loop.time() * 1000.0])
                if len(acks) == 16:
                    await ws.send_str(json.dumps({"type": "ack", "states": acks}))
                    acks = []
                recording = state["recording"]
                if not recording:
                    break
            if recording:
                await ws.send_json({"type": "control", "action": "stop"})
            if len(saved) < n:
                await receive(ws, lambda m, n=n: len(saved) >= n)
            bar.update()
    bar.close()
    return saved


def record_live(
    task: str,
    episodes: int,
    seed: int,
    out: str | Path,
    *,
    mapping: str = "clutch",
    progress: bool = False,
    task_file: str | None = None,
) -> list[dict[str, Any]]:
    """Record ``episodes`` demonstrations of ``task`` through a ``mimicrete teleop`` server run
    here (loopback), into ``out`` (demos and hand logs, as a live session writes them); returns
    the server's ``saved`` messages. Episode ``i`` plays on the server's seed ``seed + i``;
    ``progress``: a bar over the episodes; ``task_file``: the server records in that task spec
    (``mimicrete teleop --task-file``) and the person plans from its scenes, both at the spec's
    hand scale (:func:`mimicrete.teleop.view.task_calibration`)."""
    from mimicrete.teleop.live import Live
    from mimicrete.teleop.server import ServerThread, TeleopServer
    from mimicrete.teleop.view import task_calibration

    calib = task_calibration(task, task_file)  # the server's own default, from the spec
    live = Live(task, out, calibration=calib, seed=seed, mapping=mapping, task_file=task_file)
    rng = np.random.default_rng([seed, 0x11FE])
    takes = []
    first = live.next_index
    for i in range(episodes):
        scene = scene_from_env(task, seed + first + i, task_file)
        ep = synth_episode(
            scene, seed * 1_000_003 + first + i, layout="webxr", calib=calib, task_file=task_file
        )
        takes.append(quest_take(ep, rng))
    with ServerThread(TeleopServer(live)) as run:
        saved = asyncio.run(_drive(f"http://127.0.0.1:{run.port}/ws", takes, progress))
    live.flush()
    return saved
