"""A scripted human demonstrator: hand logs of a person doing a task in headset space.

``mimicrete synth-hands --task suction --episodes 60 --seed 0 --out DIR`` writes one hand log
(JSON Lines, format ``mimicrete.handlog`` v1) per episode. The demonstrator sees what a person in
the VR scene sees: where the robot's end effector, the object and the target are at the start of
the episode (:func:`scene_from_env`, the one place scene positions come from). It never reads the
simulator afterwards: every motion is planned once, open loop, like a person acting on what they
see, with generous pauses for the robot to catch up.

How a motion is made:

1. Waypoints for the robot's TCP (cup centre / point between the fingers) in the robot Base frame,
   tool pointing straight down, with the gesture to show at each (paper §3.2, Table 1).
2. A person's trajectory through them: minimum-jerk reaches at a per-episode speed, varied per
   reach; hesitations (a pause part-way); small overshoots past the goal and a correction back;
   physiological tremor (8-12 Hz, sub-millimetre) and slow sway; a slight wobble of the hand's
   orientation.
3. Gestures change through in-between finger shapes (a minimum-jerk blend of the two shapes over
   0.2-0.5 s), with the occasional single-frame tracking glitch and short tracking dropouts.
4. TCP → tool0 (the flange, ``tcp_z`` above the TCP along the tool axis) → the hand: tool0's pose
   is what ``hand_to_target`` makes of the wrist / index-proximal / middle-proximal joints through
   the calibration (``ur3_kin::hand``: tool0.x = hand.y, tool0.y = hand.x, tool0.z = −hand.z,
   origin at the wrist; headset OpenXR space → Base by :class:`mimicrete.kin.Calibration`), so the
   hand pose is that map inverted (:func:`hand_pose_for_tool0`; the forward map is only ever
   ur3-kin's), and the parametric hand (:mod:`mimicrete.hands.model`) adds the fingers.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import kin, tasks
from mimicrete.hands import layouts
from mimicrete.hands import model as hm
from mimicrete.kin import Calibration

TASKS = tasks.TASKS
HAND_RATE_HZ = 90.0

#: Gesture class (paper Table 1) → finger shape shown.
SHAPE_OF: dict[str, str] = {
    "closing": "closing",
    "opening": "opening",
    "fixed": "fixed",
    "closing_fixed": "closing",
    "closing_tightening": "tightening",
    "closing_loosening": "loosening",
    "opening_stopped": "opening",
    "fixed_stopped": "fixed",
}

#: Columns are tool0's axes in hand-frame coordinates (ur3_kin ``tool_from_hand_rotation``).
TOOL_FROM_HAND = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: tool0 pointing straight down, tool X along Base X (tile-sim ``expert::tool_down``).
TOOL_DOWN = np.diag([1.0, -1.0, -1.0])


# ----------------------------------------------------------------------------------------------
# Inverting ur3-kin's hand → tool0 map (the forward map is mimicrete.kin.hand_to_target)
# ----------------------------------------------------------------------------------------------


def _affine(calib: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(A (3, 3), b (3,))`` with ``p_base = A · p + b``, read off ur3-kin's own point map
    (:func:`mimicrete.kin.points_to_base`) so that axis conventions live only in the crate."""
    pts = kin.points_to_base(np.vstack([np.zeros(3), np.eye(3)]), calib)
    return (pts[1:] - pts[0]).T, pts[0]


def points_from_base(points: np.ndarray, calib: Any) -> np.ndarray:
    """Base points ``(..., 3)`` → the calibration's (headset) space: the inverse of
    :func:`mimicrete.kin.points_to_base`."""
    a, b = _affine(calib)
    return (np.asarray(points, dtype=np.float64) - b) @ np.linalg.inv(a).T


def hand_pose_for_tool0(
    tool0: np.ndarray, handedness: str, calib: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Invert :func:`mimicrete.kin.hand_to_target`: the hand-model wrist rotation (columns: the
    hand frame of :mod:`mimicrete.hands.model` in headset space) and wrist position that give
    ``tool0`` (``(4, 4)`` or a batch ``(n, 4, 4)`` → ``(…, 3, 3)``, ``(…, 3)``)."""
    tool0 = np.asarray(tool0, dtype=np.float64)
    r_hand_base = tool0[..., :3, :3] @ TOOL_FROM_HAND.T
    # ur3-kin negates x' for a left hand: its frame is ours · diag(-1, 1, -1)
    if handedness == "left":
        r_hand_base = r_hand_base @ np.diag([-1.0, 1.0, -1.0])
    a, _ = _affine(calib)
    rot_base_from_space = a / np.linalg.norm(a[:, 0])  # a = scale · rotation
    return rot_base_from_space.T @ r_hand_base, points_from_base(tool0[..., :3, 3], calib)


def _rot_batch(axis: int, angle: np.ndarray) -> np.ndarray:
    """Rotations ``(n, 3, 3)`` about coordinate axis ``axis`` (0 x, 1 y, 2 z)."""
    c, s = np.cos(angle), np.sin(angle)
    r = np.zeros((len(angle), 3, 3))
    i, k = [(1, 2), (2, 0), (0, 1)][axis]
    r[:, axis, axis] = 1.0
    r[:, i, i] = c
    r[:, k, k] = c
    r[:, i, k] = -s
    r[:, k, i] = s
    return r


# ----------------------------------------------------------------------------------------------
# Scene: the one place positions come from
# ----------------------------------------------------------------------------------------------


@dataclass
class Scene:
    """What the demonstrator sees at the start of an episode (Base frame, metres).

    Attributes:
        task: ``suction``, ``grip`` or ``screw``.
        episode_seed: the simulator seed of the episode.
        tcp: the end effector's TCP (cup centre / between the fingertips).
        tcp_z: distance from tool0 (flange) to the TCP along the tool axis.
        object: centre of the tile / block / nut.
        target: where the object's centre must end up.
    """

    task: str
    episode_seed: int
    tcp: np.ndarray
    tcp_z: float
    object: np.ndarray
    target: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {
            "task": self.task,
            "episode_seed": self.episode_seed,
            "tcp": np.round(self.tcp, 6).tolist(),
            "tcp_z": round(self.tcp_z, 6),
            "object": np.round(self.object, 6).tolist(),
            "target": np.round(self.target, 6).tolist(),
        }


def obs_layout(task: str) -> dict[str, slice]:
    """Fields of one observation frame (tile-sim ``Task::obs_frame_dim``)."""
    if task == "screw":
        return {
            "q": slice(0, 6),
            "tcp": slice(8, 11),
            "target": slice(11, 14),
            "object": slice(14, 17),
        }
    return {"q": slice(0, 6), "tcp": slice(7, 10), "target": slice(10, 13), "object": slice(13, 16)}


def scene_from_obs(task: str, seed: int, obs: np.ndarray, frame_dim: int) -> Scene:
    """Read a :class:`Scene` from a reset observation (newest frame last)."""
    from mimicrete import kin

    f = np.asarray(obs, dtype=np.float64).reshape(-1)[-frame_dim:]
    lay = obs_layout(task)
    tcp = f[lay["tcp"]]
    tool0 = kin.fk(f[lay["q"]], model="ur3")
    return Scene(
        task,
        int(seed),
        tcp,
        float(np.linalg.norm(tool0[:3, 3] - tcp)),
        f[lay["object"]],
        f[lay["target"]],
    )


def have_simulator() -> bool:
    """Whether ``mimicrete._native`` was built with the simulator (``tile-sim``) bindings."""
    from mimicrete import _native

    return hasattr(_native, "SimEnv")


def scene_from_env(task: str, seed: int) -> Scene:
    """The scene of episode ``seed`` as the simulator resets it (the one switch for where the
    demonstrator's knowledge comes from): positions of the end effector, the object and the
    target, which a person sees in the VR scene."""
    from mimicrete import _native

    if not have_simulator():
        raise RuntimeError(
            "mimicrete._native was built without the simulator bindings (tile-sim); "
            "rebuild with `make native`"
        )
    env = _native.SimEnv(tasks.get(task).sim)
    env.reset(int(seed))
    snap = env.snapshot()
    tcp = np.array(snap["tcp"]["t"], dtype=np.float64)
    tool0 = np.array(snap["tool0"]["t"], dtype=np.float64)
    return Scene(
        task,
        int(seed),
        tcp,
        float(np.linalg.norm(tool0 - tcp)),
        np.array(snap["object"]["t"], dtype=np.float64),
        np.array(snap["target"]["t"], dtype=np.float64),
    )


# ----------------------------------------------------------------------------------------------
# Human motion
# ----------------------------------------------------------------------------------------------


def min_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile ``10s³ − 15s⁴ + 6s⁵`` on ``s ∈ [0, 1]``."""
    s = np.clip(s, 0.0, 1.0)
    return s**3 * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclass
class Person:
    """Per-episode traits of the demonstrator."""

    speed: float  # typical hand speed during reaches, m/s
    hand_scale: float
    handedness: str
    tremor_mm: float
    sway_mm: float
    hesitancy: float  # probability that a reach pauses part-way
    overshoot: float  # typical overshoot as a share of the reach distance


class Motion:
    """Accumulates a TCP path (Base), a gesture-shape track and keyframes at 90 Hz."""

    def __init__(
        self, start: np.ndarray, shape: np.ndarray, rng: np.random.Generator, person: Person
    ) -> None:
        self.dt = 1.0 / HAND_RATE_HZ
        self.rng = rng
        self.person = person
        self.pos: list[np.ndarray] = [np.asarray(start, dtype=np.float64)]
        self.shape: list[np.ndarray] = [np.asarray(shape, dtype=np.float64)]
        self.phase: list[str] = ["start"]
        self.transport: list[bool] = [False]

    @property
    def here(self) -> np.ndarray:
        return self.pos[-1]

    def _append(self, pos: np.ndarray, shapes: np.ndarray, phase: str, transport: bool) -> None:
        self.pos.extend(pos)
        self.shape.extend(shapes)
        self.phase.extend([phase] * len(pos))
        self.transport.extend([transport] * len(pos))

    def hold(self, seconds: float, phase: str = "hold") -> None:
        n = max(1, int(round(seconds / self.dt)))
        self._append(
            np.repeat(self.here[None], n, 0), np.repeat(self.shape[-1][None], n, 0), phase, False
        )

    def gesture(self, target_shape: hm.HandShape, seconds: float, phase: str = "gesture") -> None:
        """Change the finger shape through in-between shapes while the hand holds still."""
        n = max(2, int(round(seconds / self.dt)))
        a = self.shape[-1]
        b = hm.jitter_shape(target_shape, self.rng, sd=0.03).as_array()
        w = min_jerk(np.arange(1, n + 1) / n)[:, None]
        self._append(np.repeat(self.here[None], n, 0), (1 - w) * a + w * b, phase, False)

    def _leg(self, goal: np.ndarray, seconds: float, phase: str, transport: bool) -> None:
        n = max(2, int(round(seconds / self.dt)))
        s = min_jerk(np.arange(1, n + 1) / n)[:, None]
        start = self.here
        self._append(
            start + s * (goal - start), np.repeat(self.shape[-1][None], n, 0), phase, transport
        )

    def reach(
        self, goal: np.ndarray, phase: str, precise: bool = False, transport: bool = True
    ) -> None:
        """A human reach: min-jerk, maybe a hesitation part-way, maybe an overshoot + correction.
        ``precise`` reaches (the last centimetres to a grasp) are slower and overshoot less."""
        goal = np.asarray(goal, dtype=np.float64)
        rng, p = self.rng, self.person
        d = float(np.linalg.norm(goal - self.here))
        if d < 1e-6:
            return
        speed = p.speed * rng.uniform(0.75, 1.25) * (0.4 if precise else 1.0)
        seconds = max(0.35, 1.875 * d / speed)  # min-jerk peak speed = 1.875 · mean speed
        if rng.random() < p.hesitancy and d > 0.05:
            frac = rng.uniform(0.4, 0.7)
            mid = self.here + frac * (goal - self.here) + rng.normal(scale=0.004, size=3)
            self._leg(mid, seconds * frac, phase, transport)
            self.hold(rng.uniform(0.1, 0.45), phase)
            seconds *= 1.0 - frac
        over = p.overshoot * (0.3 if precise else 1.0) * rng.uniform(0.3, 1.5)
        if d > 0.03 and over > 0.0:
            direction = (goal - self.here) / max(np.linalg.norm(goal - self.here), 1e-9)
            past = goal + direction * min(over * d, 0.012) + rng.normal(scale=0.0015, size=3)
            self._leg(past, seconds, phase, transport)
            self._leg(goal, rng.uniform(0.2, 0.4), phase + "_correct", False)
        else:
            self._leg(goal, seconds, phase, transport)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, list[str], np.ndarray]:
        return np.array(self.pos), np.array(self.shape), self.phase, np.array(self.transport)


def _slow_noise(n: int, dt: float, rng: np.random.Generator, tau: float = 0.4) -> np.ndarray:
    """Unit-variance low-pass noise ``(n, 3)`` (exponential kernel of time constant ``tau``)."""
    m = int(5 * tau / dt)
    white = rng.normal(size=(n + m - 1, 3))
    k = np.exp(-np.arange(m) * dt / tau)
    k /= np.sqrt(np.sum(k**2))
    return np.stack([np.convolve(white[:, i], k, mode="valid") for i in range(3)], axis=1)


def _tremor(n: int, dt: float, rng: np.random.Generator, person: Person) -> np.ndarray:
    """Physiological tremor (8-12 Hz) plus slow sway, ``(n, 3)`` metres."""
    t = np.arange(n) * dt
    out = np.zeros((n, 3))
    for _ in range(3):
        f = rng.uniform(8.0, 12.0)
        amp = person.tremor_mm * 1e-3 / 3.0
        out += amp * np.sin(2 * np.pi * f * t[:, None] + rng.uniform(0, 2 * np.pi, size=3))
    return out + person.sway_mm * 1e-3 * _slow_noise(n, dt, rng)


_UP = np.array([0.0, 0.0, 1.0])


def _approach_and_grasp(
    m: Motion,
    above: np.ndarray,
    *,
    approach: tuple[float, float],
    settle: tuple[float, float],
    grasp_at: Any,
    settled: tuple[float, float],
    close: hm.HandShape,
    grasp: tuple[float, float],
) -> None:
    """Reach ``approach`` (m, uniform range) above ``above``, settle, descend precisely to
    ``grasp_at()`` (called only then, so its draws come after the settle's), settle, close the
    hand, hold ``grasp`` seconds while the end effector closes. Ranges are drawn from ``m.rng``."""
    rng = m.rng
    m.reach(above + _UP * rng.uniform(*approach), "approach")
    m.hold(rng.uniform(*settle), "settle")
    m.reach(grasp_at(), "descend", precise=True)
    m.hold(rng.uniform(*settled), "settle")
    m.gesture(close, rng.uniform(0.2, 0.5), "close")
    m.hold(rng.uniform(*grasp), "grasp")


def _carry_and_place(
    m: Motion,
    target: np.ndarray,
    *,
    held_below: float,
    carry: tuple[float, float],
    lower: tuple[float, float],
    release_shape: hm.HandShape,
    release: tuple[float, float],
) -> None:
    """Lift, carry to ``carry`` above ``target`` (plus ``held_below``, how far the object's
    centre hangs below the TCP), settle, lower precisely to ``lower`` above it, place, open the
    hand, hold ``release`` seconds, retreat upwards."""
    rng = m.rng
    m.reach(m.here + _UP * rng.uniform(0.08, 0.12), "lift")
    m.reach(target + _UP * (held_below + rng.uniform(*carry)), "carry")
    m.hold(rng.uniform(0.3, 0.6), "settle")
    m.reach(target + _UP * (held_below + rng.uniform(*lower)), "lower", precise=True)
    m.hold(rng.uniform(0.5, 0.9), "place")
    m.gesture(release_shape, rng.uniform(0.2, 0.5), "release")
    m.hold(rng.uniform(*release), "release")
    m.reach(m.here + _UP * 0.08, "retreat")


def plan_task(scene: Scene, rng: np.random.Generator, person: Person) -> Motion:
    """The TCP path and gestures of one demonstration of ``scene.task``."""
    task = scene.task
    up = _UP
    cls_open = "opening_stopped" if task == "screw" else "opening"
    cls_close = "closing_fixed" if task == "screw" else "closing"
    shp = {c: hm.GESTURE_SHAPES[SHAPE_OF[c]] for c in SHAPE_OF}
    m = Motion(scene.tcp, hm.jitter_shape(shp[cls_open], rng, 0.03).as_array(), rng, person)
    m.hold(rng.uniform(0.3, 0.8), "start")
    obj, tgt = scene.object, scene.target
    if task == "suction":
        grasp = obj + up * obj[2]  # tile centre sits half a thickness above the table (z = 0)
        clearance = rng.uniform(0.008, 0.016)
        _approach_and_grasp(
            m,
            grasp,
            approach=(0.06, 0.10),
            settle=(0.3, 0.7),
            grasp_at=lambda: grasp + up * clearance,
            settled=(0.5, 0.9),
            close=shp[cls_close],
            grasp=(0.5, 0.9),
        )
        _carry_and_place(
            m,
            tgt,
            held_below=clearance + obj[2],  # tile centre to cup centre while held
            carry=(0.06, 0.10),
            lower=(0.0, 0.006),
            release_shape=shp[cls_open],
            release=(0.3, 0.6),
        )
    elif task == "grip":
        _approach_and_grasp(
            m,
            obj,
            approach=(0.08, 0.12),
            settle=(0.3, 0.7),
            grasp_at=lambda: obj + up * rng.uniform(-0.003, 0.003),
            settled=(0.6, 1.0),
            close=shp[cls_close],
            grasp=(0.9, 1.3),  # fingers close at 0.1 m/s
        )
        _carry_and_place(
            m,
            tgt,
            held_below=0.0,
            carry=(0.07, 0.10),
            lower=(0.002, 0.006),
            release_shape=shp[cls_open],
            release=(0.6, 1.0),
        )
    elif task == "screw":
        _approach_and_grasp(
            m,
            obj,
            approach=(0.07, 0.10),
            settle=(0.4, 0.8),
            grasp_at=obj.copy,
            settled=(0.7, 1.1),
            close=shp[cls_close],
            grasp=(0.9, 1.3),
        )
        m.gesture(shp["closing_tightening"], rng.uniform(0.25, 0.5), "tighten")
        # keep tightening, following the nut down, until it sits at the target (seen in VR)
        seconds = rng.uniform(4.5, 5.5)
        n = int(round(seconds * HAND_RATE_HZ))
        follow = np.linspace(0.0, 1.0, n)[:, None] ** 1.0
        start = m.here
        path = start + np.clip(follow * 1.15, 0, 1) * (tgt - start)
        m._append(path, np.repeat(m.shape[-1][None], n, 0), "tighten", False)
        m.gesture(shp["closing_fixed"], rng.uniform(0.2, 0.4), "stop")
        m.gesture(shp["opening_stopped"], rng.uniform(0.2, 0.5), "release")
        m.hold(rng.uniform(0.4, 0.8), "release")
        m.reach(m.here + up * 0.08, "retreat")
    else:
        raise ValueError(f"unknown task {task!r}; known: {TASKS}")
    m.hold(rng.uniform(0.3, 0.6), "end")
    return m


@dataclass
class Episode:
    """One synthesised demonstration: frames in headset space and what made them."""

    header: dict[str, Any]
    t: np.ndarray  # (T,)
    tracked: np.ndarray  # (T,) bool
    joints: np.ndarray  # (T, N, 3) in the header's layout and space
    phases: list[str]
    tool0: np.ndarray  # (T, 4, 4) the tool0 pose each frame is meant to command (Base)


def synth_episode(
    scene: Scene,
    seed: int,
    *,
    layout: str = "openxr",
    calib: Calibration | None = None,
    handedness: str = "right",
) -> Episode:
    """Synthesise one demonstration of ``scene``; the same ``(scene, seed)`` gives the same
    episode."""
    layout = layouts.check_layout(layout)
    calib = calib or Calibration()
    rng = np.random.default_rng([seed, scene.episode_seed & 0xFFFFFFFF, 0x5E17])
    person = Person(
        speed=float(rng.uniform(0.15, 0.30)),
        hand_scale=float(rng.uniform(0.82, 1.18)),
        handedness=handedness,
        tremor_mm=float(rng.uniform(0.2, 0.6)),
        sway_mm=float(rng.uniform(0.2, 0.7)),
        hesitancy=float(rng.uniform(0.1, 0.4)),
        overshoot=float(rng.uniform(0.02, 0.08)),
    )
    motion = plan_task(scene, rng, person)
    tcp, shapes, phases, transport = motion.arrays()
    n = len(tcp)
    dt = 1.0 / HAND_RATE_HZ
    tcp = tcp + _tremor(n, dt, rng, person)
    # tool orientation: straight down with a slight slow wobble (< ~1°) and a personal yaw bias
    wob = np.radians(0.5) * _slow_noise(n, dt, rng, tau=0.6)
    yaw0 = rng.uniform(-0.05, 0.05)
    t = np.arange(n) * dt
    rot = (
        _rot_batch(2, yaw0 + wob[:, 2]) @ _rot_batch(0, wob[:, 0]) @ _rot_batch(1, wob[:, 1])
    ) @ TOOL_DOWN
    frames = np.zeros((n, 4, 4))
    frames[:, :3, :3] = rot
    frames[:, :3, 3] = tcp - rot[:, :, 2] * scene.tcp_z  # tool z points down, to the TCP
    frames[:, 3, 3] = 1.0
    hand_rot, wrist = hand_pose_for_tool0(frames, handedness, calib)
    glitch = np.flatnonzero(rng.random(n) < 0.004)  # one-frame finger-tracking glitches
    names = list(hm.GESTURE_SHAPES)
    for k in glitch:
        shapes[k] = hm.jitter_shape(
            hm.GESTURE_SHAPES[names[rng.integers(len(names))]], rng
        ).as_array()
    local = hm.hand_joints_local_batch(shapes, person.hand_scale, handedness)
    joints = np.einsum("nij,nkj->nki", hand_rot, local) + wrist[:, None, :]
    joints = hm.tracking_noise_batch(joints, rng, sigma=0.0004, occluded_sigma=0.004)
    tracked = np.ones(n, dtype=bool)
    moving = np.flatnonzero(transport)
    if len(moving) > 20 and rng.random() < 0.5:  # a short tracking dropout while moving
        k0 = int(moving[rng.integers(len(moving) - 12)])
        length = int(rng.integers(3, 12))
        tracked[k0 : k0 + length] = False
        joints[k0 : k0 + length] = joints[k0 - 1]  # the runtime repeats its last estimate
    out = layouts.to_layout(joints, layout)
    header = {
        "format": "mimicrete.handlog",
        "version": 1,
        "layout": layout,
        "space": calib.space,
        "handedness": handedness,
        "units": "m",
        "task": scene.task,
        "episode_seed": int(scene.episode_seed),
        "source": "mimicrete synth-hands (scripted demonstrator)",
        "extra": {
            "synth_seed": int(seed),
            "calibration": calib.to_dict(),
            "scene": scene.to_dict(),
            "person": {
                "speed_m_s": round(person.speed, 4),
                "hand_scale": round(person.hand_scale, 4),
                "tremor_mm": round(person.tremor_mm, 3),
            },
            "rate_hz": HAND_RATE_HZ,
        },
    }
    return Episode(header, t, tracked, out, phases, frames)


def write_handlog(path: str | Path, ep: Episode) -> Path:
    """Write an :class:`Episode` as a hand log (JSON Lines, coordinates rounded to 10 µm)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as f:
        f.write(json.dumps(ep.header, separators=(",", ":")) + "\n")
        rounded = np.round(ep.joints, 5)
        for t, tr, j in zip(ep.t, ep.tracked, rounded, strict=True):
            f.write(
                json.dumps(
                    {"t": round(float(t), 6), "tracked": bool(tr), "joints": j.tolist()},
                    separators=(",", ":"),
                )
                + "\n"
            )
    return path


def episode_seeds(seed: int, episodes: int) -> list[int]:
    """The simulator seeds of ``episodes`` demonstrations drawn from ``seed`` (u64 each)."""
    rng = np.random.default_rng([seed, 0xE915])
    return [int(s) for s in rng.integers(0, 2**63 - 1, size=episodes, dtype=np.int64)]


def synth_hands(
    task: str,
    episodes: int,
    seed: int,
    out: str | Path,
    *,
    layout: str = "openxr",
    handedness: str = "right",
    scene_fn: Any = None,
    progress: bool = False,
) -> list[Path]:
    """Write ``episodes`` hand logs for ``task`` into ``out``; returns their paths.

    ``scene_fn(task, episode_seed) -> Scene`` defaults to :func:`scene_from_env`.
    """
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; known: {TASKS}")
    scene_fn = scene_fn or scene_from_env
    out = Path(out)
    paths = []
    seeds = episode_seeds(seed, episodes)
    it: Any = enumerate(seeds)
    if progress:
        from tqdm import tqdm

        it = tqdm(it, total=episodes, desc=f"synth {task}", unit="ep")
    for i, ep_seed in it:
        scene = scene_fn(task, ep_seed)
        ep = synth_episode(scene, seed * 1_000_003 + i, layout=layout, handedness=handedness)
        paths.append(write_handlog(out / f"{task}_{i:04d}.handlog.jsonl", ep))
    return paths
