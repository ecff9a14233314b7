"""Labelled gesture **sequences** (frames in time, each with the class the person shows), for the
temporal model and for comparing models on streams rather than on single poses.

Two sources, both from the scripted demonstrator's person (:mod:`mimicrete.demonstrator`,
:mod:`mimicrete.demonstrator.motion`: minimum-jerk reaches, tremor and sway, gestures changing
through in-between finger shapes, one-frame tracking glitches, short dropouts):

* **episodes** (:func:`demo_sequences`): whole task demonstrations, exactly as
  ``mimicrete synth-hands`` makes them; the demonstrator labels each frame
  (:attr:`mimicrete.demonstrator.SynthEpisode.gestures`). They show only the classes a task uses
  (suction/grip: ``closing``/``opening``; screw: ``opening_stopped`` → ``closing_fixed`` →
  ``closing_tightening`` → ``closing_fixed`` → ``opening_stopped``).
* **drills** (:func:`drill_sequence`): the same person cycling through every class of a model
  task in random order, holding each 0.5-2.5 s while moving the hand about the workspace and
  turning it, as a user does when teaching gestures: every class and every change between two
  classes occurs.

A frame's label is the class the person shows: during a change of gesture the old class until the
in-between shape is half-way, the new one from there on (``changing`` marks those frames).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimicrete.hands import layouts
from mimicrete.hands import model as hm

from .classes import CLASS_SHAPE, TASK_CLASSES, TASK_MODEL

#: Demonstrator tasks whose gestures each model task reads.
MODEL_TASK_DEMOS: dict[str, tuple[str, ...]] = {"grip": ("suction", "grip"), "screw": ("screw",)}


@dataclass
class GestureSequence:
    """Frames of one hand in time order and the class shown in each.

    Attributes:
        t: ``(T,)`` seconds.
        joints: ``(T, N, 3)`` in ``layout`` order (tracking space, metres).
        labels: ``(T,)`` class names.
        tracked: ``(T,)`` bool; untracked frames repeat the last estimate and are not classified.
        changing: ``(T,)`` bool; the frame is part of a change of gesture.
        handedness: ``left``/``right``.
        layout: the joint order.
        source: where it came from (e.g. ``episode screw seed 12``).
    """

    t: np.ndarray
    joints: np.ndarray
    labels: np.ndarray
    tracked: np.ndarray
    changing: np.ndarray
    handedness: str = "right"
    layout: str = "openxr"
    source: str = ""

    def __len__(self) -> int:
        return len(self.t)


def demo_sequences(
    task: str, seeds: list[int] | range, layout: str = "openxr"
) -> list[GestureSequence]:
    """One demonstrator episode per seed for each demonstrator task of model task ``task``
    (``grip``: suction and grip episodes; ``screw``: screw episodes). The seed is both the
    simulator's episode seed and the person's."""
    from mimicrete import demonstrator as sy

    out = []
    for demo in MODEL_TASK_DEMOS[TASK_MODEL.get(task, task)]:
        for s in seeds:
            ep = sy.synth_episode(sy.scene_from_env(demo, int(s)), int(s), layout=layout)
            out.append(
                GestureSequence(
                    ep.t,
                    ep.joints,
                    np.array(ep.gestures),
                    ep.tracked,
                    ep.changing,
                    ep.header["handedness"],
                    layout,
                    f"episode {demo} seed {s}",
                )
            )
    return out


def _rotations(rotvecs: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(n, 3, 3)`` of rotation vectors ``(n, 3)`` (Rodrigues)."""
    angle = np.linalg.norm(rotvecs, axis=-1)
    axis = rotvecs / np.maximum(angle, 1e-12)[:, None]
    k = np.zeros((len(rotvecs), 3, 3))
    k[:, 0, 1], k[:, 0, 2] = -axis[:, 2], axis[:, 1]
    k[:, 1, 0], k[:, 1, 2] = axis[:, 2], -axis[:, 0]
    k[:, 2, 0], k[:, 2, 1] = -axis[:, 1], axis[:, 0]
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


#: The drill's neutral hand orientation in OpenXR/WebXR ``local`` space (x right, y up, z toward
#: the user): palm down, fingers pointing away from the user (columns: the hand frame's axes).
_PALM_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def drill_sequence(
    task: str,
    seed: int,
    *,
    changes: int = 10,
    layout: str = "openxr",
    handedness: str | None = None,
) -> GestureSequence:
    """A person showing every class of ``task`` (``grip``: 3, ``screw``: 5) in random order
    (``changes`` changes of gesture, ~25 s), moving and turning the hand while holding each.

    The hand wanders in a 0.5 × 0.3 × 0.4 m box in front of the head (``local`` space: y up,
    −z ahead), turned up to ~±45° about every axis from palm-down, slowly; handedness right
    (80 %) or left unless given. Same ``(task, seed)``, same drill.
    """
    from mimicrete.demonstrator.motion import Motion, Person, _slow_noise, _tremor, tracked_hand
    from mimicrete.demonstrator.scene import HAND_RATE_HZ

    task = TASK_MODEL.get(task, task)
    classes = TASK_CLASSES[task]
    rng = np.random.default_rng([seed, 0xD711])
    hand = handedness or ("left" if rng.random() < 0.2 else "right")
    person = Person.draw(rng, hand)
    centre = np.array([0.15 if hand == "right" else -0.15, -0.35, -0.45])
    box = np.array([0.25, 0.15, 0.2])

    def somewhere() -> np.ndarray:
        return centre + rng.uniform(-1.0, 1.0, size=3) * box

    shape_of = {c: hm.GESTURE_SHAPES[CLASS_SHAPE[c]] for c in classes}
    current = str(classes[rng.integers(len(classes))])
    m = Motion(
        somewhere(), hm.jitter_shape(shape_of[current], rng, 0.03).as_array(), rng, person, current
    )
    m.hold(rng.uniform(0.3, 0.8), "hold")
    for _ in range(changes):
        # hold the gesture: still, or moving to another place
        for _ in range(int(rng.integers(0, 2))):
            m.reach(somewhere(), "move")
        m.hold(rng.uniform(0.3, 1.0), "hold")
        nxt = str(rng.choice([c for c in classes if c != current]))
        m.gesture(shape_of[nxt], rng.uniform(0.2, 0.5), "change", nxt)
        current = nxt
    m.hold(rng.uniform(0.5, 1.0), "hold")
    pos, shapes, _, _ = m.arrays()
    labels, changing = m.gestures()
    n = len(pos)
    dt = 1.0 / HAND_RATE_HZ
    pos = pos + _tremor(n, dt, rng, person)
    tilt = 0.45 * _slow_noise(n, dt, rng, tau=1.5) + rng.uniform(-0.4, 0.4, size=3)
    rot = _rotations(tilt) @ _PALM_DOWN
    joints = tracked_hand(shapes, rot, pos, person, rng)
    tracked = np.ones(n, dtype=bool)
    if rng.random() < 0.5:  # a short tracking dropout
        k0 = int(rng.integers(1, n - 12))
        tracked[k0 : k0 + int(rng.integers(3, 12))] = False
        joints[~tracked] = joints[k0 - 1]
    return GestureSequence(
        np.arange(n) * dt,
        layouts.to_layout(joints, layout),
        np.array(labels),
        tracked,
        changing,
        hand,
        layout,
        f"drill {task} seed {seed}",
    )


def sequence_dataset(
    task: str,
    seeds: list[int] | range,
    *,
    episodes: bool = True,
    drills: bool = True,
    layout: str = "openxr",
) -> list[GestureSequence]:
    """Demonstrator episodes and/or drills of model task ``task`` for each seed."""
    out: list[GestureSequence] = []
    if episodes:
        out.extend(demo_sequences(task, seeds, layout))
    if drills:
        out.extend(drill_sequence(task, int(s), layout=layout) for s in seeds)
    return out
