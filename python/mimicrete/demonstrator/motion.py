"""How the scripted person moves: minimum-jerk reaches, pauses, gestures, tremor and slow drift,
planned per task from the scene (:mod:`.scene`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from mimicrete import tasks
from mimicrete.hands import model as hm

from .scene import (
    HAND_RATE_HZ,
    SHAPE_OF,
    Scene,
    square_turn,
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

    @classmethod
    def draw(cls, rng: np.random.Generator, handedness: str) -> Person:
        """A demonstrator drawn from ``rng``: speed, hand size, tremor, sway, hesitancy and
        overshoot uniform in their ranges."""
        return cls(
            speed=float(rng.uniform(0.15, 0.30)),
            hand_scale=float(rng.uniform(0.82, 1.18)),
            handedness=handedness,
            tremor_mm=float(rng.uniform(0.2, 0.6)),
            sway_mm=float(rng.uniform(0.2, 0.7)),
            hesitancy=float(rng.uniform(0.1, 0.4)),
            overshoot=float(rng.uniform(0.02, 0.08)),
        )


class Motion:
    """Accumulates a TCP path (Base), the tool's turn about Base Z, a gesture-shape track and
    keyframes at 90 Hz."""

    def __init__(
        self,
        start: np.ndarray,
        shape: np.ndarray,
        rng: np.random.Generator,
        person: Person,
        label: str = "",
    ) -> None:
        self.dt = 1.0 / HAND_RATE_HZ
        self.rng = rng
        self.person = person
        self.pos: list[np.ndarray] = [np.asarray(start, dtype=np.float64)]
        #: how far the person has turned the tool about Base Z from straight down (rad): the
        #: wrist turns only where a task asks for it (the head square to a tile, ``place``)
        self.yaw: list[float] = [0.0]
        self.shape: list[np.ndarray] = [np.asarray(shape, dtype=np.float64)]
        self.phase: list[str] = ["start"]
        self.transport: list[bool] = [False]
        # the gesture class the person shows each frame (paper Table 1): during a change of
        # gesture the old class until the in-between shape is half-way, the new one after it
        self.label: list[str] = [label]
        self.changing: list[bool] = [False]  # frame is part of a change of gesture

    @property
    def here(self) -> np.ndarray:
        return self.pos[-1]

    def _append(
        self,
        pos: np.ndarray,
        shapes: np.ndarray,
        phase: str,
        transport: bool,
        labels: list[str] | None = None,
        yaw: np.ndarray | None = None,
    ) -> None:
        self.pos.extend(pos)
        self.yaw.extend([self.yaw[-1]] * len(pos) if yaw is None else yaw)
        self.shape.extend(shapes)
        self.phase.extend([phase] * len(pos))
        self.transport.extend([transport] * len(pos))
        self.label.extend(labels or [self.label[-1]] * len(pos))
        self.changing.extend([labels is not None] * len(pos))

    def hold(self, seconds: float, phase: str = "hold") -> None:
        n = max(1, int(round(seconds / self.dt)))
        self._append(
            np.repeat(self.here[None], n, 0), np.repeat(self.shape[-1][None], n, 0), phase, False
        )

    def gesture(
        self,
        target_shape: hm.HandShape,
        seconds: float,
        phase: str = "gesture",
        label: str | None = None,
    ) -> None:
        """Change the finger shape through in-between shapes while the hand holds still; the
        frames are labelled gesture class ``label`` from the half-way shape on (the previous
        class before it; ``label`` None keeps the previous class throughout)."""
        n = max(2, int(round(seconds / self.dt)))
        a = self.shape[-1]
        b = hm.jitter_shape(target_shape, self.rng, sd=0.03).as_array()
        w = min_jerk(np.arange(1, n + 1) / n)[:, None]
        before = self.label[-1]
        labels = [label if label is not None and wk >= 0.5 else before for wk in w[:, 0]]
        self._append(np.repeat(self.here[None], n, 0), (1 - w) * a + w * b, phase, False, labels)

    def _leg(
        self,
        goal: np.ndarray,
        seconds: float,
        phase: str,
        transport: bool,
        yaw: float | None = None,
    ) -> None:
        """A min-jerk leg to ``goal``, the wrist turning to ``yaw`` on the way (None: as it is)."""
        n = max(2, int(round(seconds / self.dt)))
        s = min_jerk(np.arange(1, n + 1) / n)[:, None]
        start, yaw0 = self.here, self.yaw[-1]
        turn = None if yaw is None else yaw0 + s[:, 0] * (yaw - yaw0)
        self._append(
            start + s * (goal - start),
            np.repeat(self.shape[-1][None], n, 0),
            phase,
            transport,
            yaw=turn,
        )

    def reach(
        self,
        goal: np.ndarray,
        phase: str,
        precise: bool = False,
        transport: bool = True,
        yaw: float | None = None,
    ) -> None:
        """A human reach: min-jerk, maybe a hesitation part-way, maybe an overshoot + correction.
        ``precise`` reaches (the last centimetres to a grasp) are slower and overshoot less.
        ``yaw``: the wrist turns the tool to it about Base Z over the reach (None: it stays)."""
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
            turn = None if yaw is None else self.yaw[-1] + frac * (yaw - self.yaw[-1])
            self._leg(mid, seconds * frac, phase, transport, turn)
            self.hold(rng.uniform(0.1, 0.45), phase)
            seconds *= 1.0 - frac
        over = p.overshoot * (0.3 if precise else 1.0) * rng.uniform(0.3, 1.5)
        if d > 0.03 and over > 0.0:
            direction = (goal - self.here) / max(np.linalg.norm(goal - self.here), 1e-9)
            past = goal + direction * min(over * d, 0.012) + rng.normal(scale=0.0015, size=3)
            self._leg(past, seconds, phase, transport, yaw)
            self._leg(goal, rng.uniform(0.2, 0.4), phase + "_correct", False)
        else:
            self._leg(goal, seconds, phase, transport, yaw)

    def set_down(self, goal: np.ndarray, phase: str) -> None:
        """The last centimetre or two onto a surface (the cups onto a tile, a held tile onto its
        pad): slow and straight, no hesitation and no overshoot, as a person feels for a contact
        they must not press through."""
        self._leg(goal, self.rng.uniform(0.6, 1.0), phase, False)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, list[str], np.ndarray]:
        return np.array(self.pos), np.array(self.shape), self.phase, np.array(self.transport)

    def yaws(self) -> np.ndarray:
        """Per frame: the tool's planned turn about Base Z from straight down (rad)."""
        return np.array(self.yaw)

    def gestures(self) -> tuple[list[str], np.ndarray]:
        """Per frame: the gesture class shown, and whether the frame is part of a change."""
        return list(self.label), np.array(self.changing)


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


def tracked_hand(
    shapes: np.ndarray,
    hand_rot: np.ndarray,
    wrist: np.ndarray,
    person: Person,
    rng: np.random.Generator,
) -> np.ndarray:
    """The joints a hand tracker reports ``(n, 26, 3)`` for finger ``shapes`` ``(n, 7)`` (changed
    in place: one-frame finger-tracking glitches, 0.4 % of frames, show a random gesture's
    shape) on a hand of ``person``'s size and handedness at ``hand_rot`` ``(n, 3, 3)`` and
    ``wrist`` ``(n, 3)``, with tracking noise (more on occluded joints)."""
    names = list(hm.GESTURE_SHAPES)
    for k in np.flatnonzero(rng.random(len(shapes)) < 0.004):
        shapes[k] = hm.jitter_shape(
            hm.GESTURE_SHAPES[names[rng.integers(len(names))]], rng
        ).as_array()
    local = hm.hand_joints_local_batch(shapes, person.hand_scale, person.handedness)
    joints = np.einsum("nij,nkj->nki", hand_rot, local) + wrist[:, None, :]
    return hm.tracking_noise_batch(joints, rng, sigma=0.0004, occluded_sigma=0.004)


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
    close_label: str | None = None,
    touch: tuple[float, float] | None = None,
    yaw: float | None = None,
) -> None:
    """Reach ``approach`` (m, uniform range) above ``above``, settle, descend precisely to
    ``grasp_at()`` (called only then, so its draws come after the settle's), settle, close the
    hand, hold ``grasp`` seconds while the end effector closes. Ranges are drawn from ``m.rng``.
    ``touch`` (m): from there, set the end effector down onto ``above`` (a surface: the tile's
    face) to that range above it (:meth:`Motion.set_down`); ``yaw``: turn the tool to it (rad
    about Base Z) on the way over."""
    rng = m.rng
    m.reach(above + _UP * rng.uniform(*approach), "approach", yaw=yaw)
    m.hold(rng.uniform(*settle), "settle")
    m.reach(grasp_at(), "descend", precise=True)
    if touch is not None:
        m.set_down(above + _UP * rng.uniform(*touch), "touch")
    m.hold(rng.uniform(*settled), "settle")
    m.gesture(close, rng.uniform(0.2, 0.5), "close", close_label)
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
    release_label: str | None = None,
    set_down: tuple[float, float] | None = None,
    yaw: float | None = None,
) -> None:
    """Lift, carry to ``carry`` above ``target`` (plus ``held_below``, how far the object's
    centre hangs below the TCP), settle, lower precisely to ``lower`` above it, place, open the
    hand, hold ``release`` seconds, retreat upwards. ``set_down`` (m): from ``lower``, look at
    the object over the target for a moment, then set it down to that range above the target
    (:meth:`Motion.set_down`; what the look shows moves the hand then: :mod:`.look`); ``yaw``:
    turn the tool, and the object with it, to it (rad about Base Z) over the carry."""
    rng = m.rng
    m.reach(m.here + _UP * rng.uniform(0.08, 0.12), "lift")
    m.reach(target + _UP * (held_below + rng.uniform(*carry)), "carry", yaw=yaw)
    m.hold(rng.uniform(0.3, 0.6), "settle")
    m.reach(target + _UP * (held_below + rng.uniform(*lower)), "lower", precise=True)
    if set_down is not None:  # a look at the object over the target first (.look)
        m.hold(rng.uniform(0.2, 0.4), "look")
        m.set_down(target + _UP * (held_below + rng.uniform(*set_down)), "set_down")
    m.hold(rng.uniform(0.5, 0.9), "place")
    m.gesture(release_shape, rng.uniform(0.2, 0.5), "release", release_label)
    m.hold(rng.uniform(*release), "release")
    m.reach(m.here + _UP * 0.08, "retreat")


#: Per task, the ranges (m above the grasp point, s) of :func:`_approach_and_grasp`.
_GRASP: dict[str, dict[str, tuple[float, float]]] = {
    "suction": {
        "approach": (0.06, 0.10),
        "settle": (0.3, 0.7),
        "settled": (0.5, 0.9),
        "grasp": (0.5, 0.9),
    },
    # the gripper's fingers close at 0.1 m/s
    "grip": {
        "approach": (0.08, 0.12),
        "settle": (0.3, 0.7),
        "settled": (0.6, 1.0),
        "grasp": (0.9, 1.3),
    },
    "screw": {
        "approach": (0.07, 0.10),
        "settle": (0.4, 0.8),
        "settled": (0.7, 1.1),
        "grasp": (0.9, 1.3),
    },
}
# the row's person handles each tile as TileSuction's (the same suction head and tile)
_GRASP["row"] = _GRASP["suction"]
# TilePlace's cups seal only with their lips within 3 mm of the face: the person comes down to
# 12-20 mm above it, then sets the cups down to 1-2 mm above it (the hand's tremor and sway,
# about +-2 mm, keep the lips off the face's far side and out of it), and holds still with the
# suction shown until the vacuum has built up (0.1 s, tile_place.toml)
_GRASP["place"] = {**_GRASP["suction"], "touch": (0.001, 0.002)}
#: The tasks the scripted person demonstrates: one grasp, then (but for the screw) one place;
#: the row (``TileRow``) three of them in one episode, tile ``i`` onto pad ``i``.
TASKS: tuple[str, ...] = tuple(_GRASP)
#: Per pick-and-place task, the ranges (m above the target, s) of :func:`_carry_and_place`.
_PLACE: dict[str, dict[str, tuple[float, float]]] = {
    "suction": {"carry": (0.06, 0.10), "lower": (0.0, 0.006), "release": (0.3, 0.6)},
    "grip": {"carry": (0.07, 0.10), "lower": (0.002, 0.006), "release": (0.6, 1.0)},
    # TilePlace: let go at most 5 mm above where the tile comes to rest, and never press the
    # cups more than 3 mm into the held tile's face (a protective stop): lowered to 12-20 mm,
    # then set down to 1.5-3 mm above its resting height (the hand's +-2 mm keep it in the
    # 8 mm between the two)
    "place": {
        "carry": (0.06, 0.10),
        "lower": (0.012, 0.02),
        "set_down": (0.0015, 0.003),
        "release": (0.3, 0.6),
    },
}
_PLACE["row"] = _PLACE["suction"]
#: The tasks whose person squares the suction head to the tile (its four cups repeat every
#: 90°: turned square, every lip lands on the face) and the held tile to its pad (the success
#: asks for its edges within 2° of the pad's): TilePlace.
_SQUARE: tuple[str, ...] = ("place",)


def check_task(task: str) -> None:
    """Refuse a task the scripted person does not demonstrate: a
    :class:`mimicrete.tasks.NotBuiltError` for a task of the table whose plan is not built (none
    today), a ValueError for a name that is not a task (``task``: the short name, ``suction``)."""
    if task in TASKS:
        return
    if task in tasks.TASKS:
        raise tasks.not_built("the scripted demonstrator", task, TASKS)
    raise ValueError(f"unknown task {task!r}; known: {TASKS}")


def plan_task(scene: Scene, rng: np.random.Generator, person: Person) -> Motion:
    """The TCP path and gestures of one demonstration of ``scene.task``."""
    task = scene.task
    check_task(task)
    cls_open = "opening_stopped" if task == "screw" else "opening"
    cls_close = "closing_fixed" if task == "screw" else "closing"
    shp = {c: hm.GESTURE_SHAPES[SHAPE_OF[c]] for c in SHAPE_OF}
    m = Motion(
        scene.tcp, hm.jitter_shape(shp[cls_open], rng, 0.03).as_array(), rng, person, cls_open
    )
    m.hold(rng.uniform(0.3, 0.8), "start")
    for k, (obj, tgt) in enumerate(scene.picks()):
        if k:  # between a row's tiles: a look at the next one
            m.hold(rng.uniform(0.2, 0.5), "next")
        yaws = (scene.object_yaw, scene.target_yaw) if scene.objects is None else (0.0, 0.0)
        _pick_and_place(m, task, obj, tgt, shp, cls_open, cls_close, yaws)
    m.hold(rng.uniform(0.3, 0.6), "end")
    return m


def _pick_and_place(
    m: Motion,
    task: str,
    obj: np.ndarray,
    tgt: np.ndarray,
    shp: dict[str, hm.HandShape],
    cls_open: str,
    cls_close: str,
    yaws: tuple[float, float] = (0.0, 0.0),
) -> None:
    """One object of ``task`` from ``obj`` to ``tgt`` (the screw: tightened down to ``tgt``);
    ``yaws``: how the object and the target are turned (rad about Base Z)."""
    rng, up = m.rng, _UP
    above, held_below = obj, 0.0  # where the grasp is; how far the object hangs below the TCP
    head = over_target = None  # the tool's yaw over the object, over the target (None: as is)
    if task in _SQUARE:
        head = m.yaw[-1] + square_turn(m.yaw[-1], yaws[0])
        over_target = head + square_turn(yaws[0], yaws[1])
    if task in ("suction", "row"):
        above = obj + up * obj[2]  # tile centre sits half a thickness above the table (z = 0)
        clearance = rng.uniform(0.008, 0.016)
        held_below = clearance + obj[2]  # tile centre to cup centre while held

        def grasp_at() -> np.ndarray:
            return above + up * clearance
    elif task == "place":
        above = obj + up * obj[2]  # the tile's face
        held_below = obj[2]  # the hold draws the face onto the lips: the centre hangs below

        def grasp_at() -> np.ndarray:  # where the cups are set down from (_GRASP's touch)
            return above + up * rng.uniform(0.012, 0.02)
    elif task == "grip":

        def grasp_at() -> np.ndarray:
            return obj + up * rng.uniform(-0.003, 0.003)
    elif task == "screw":

        def grasp_at() -> np.ndarray:
            return obj.copy()
    else:  # pragma: no cover - check_task refused it
        raise ValueError(f"unknown task {task!r}; known: {TASKS}")
    _approach_and_grasp(
        m,
        above,
        grasp_at=grasp_at,
        close=shp[cls_close],
        close_label=cls_close,
        yaw=head,
        **_GRASP[task],
    )
    if task in _PLACE:
        _carry_and_place(
            m,
            tgt,
            held_below=held_below,
            release_shape=shp[cls_open],
            release_label=cls_open,
            yaw=over_target,
            **_PLACE[task],
        )
    else:  # screw
        m.gesture(
            shp["closing_tightening"], rng.uniform(0.25, 0.5), "tighten", "closing_tightening"
        )
        # keep tightening, following the nut down, until it sits at the target (seen in VR)
        seconds = rng.uniform(4.5, 5.5)
        n = int(round(seconds * HAND_RATE_HZ))
        follow = np.linspace(0.0, 1.0, n)[:, None] ** 1.0
        start = m.here
        path = start + np.clip(follow * 1.15, 0, 1) * (tgt - start)
        m._append(path, np.repeat(m.shape[-1][None], n, 0), "tighten", False)
        m.gesture(shp["closing_fixed"], rng.uniform(0.2, 0.4), "stop", "closing_fixed")
        m.gesture(shp["opening_stopped"], rng.uniform(0.2, 0.5), "release", "opening_stopped")
        m.hold(rng.uniform(0.4, 0.8), "release")
        m.reach(m.here + up * 0.08, "retreat")
