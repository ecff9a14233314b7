"""A scripted human demonstrator: hand logs of a person doing a task in headset space.

``mimicrete synth-hands --task suction --episodes 60 --seed 0 --out DIR`` writes one hand log
(JSON Lines, format ``mimicrete.handlog`` v1) per episode. The demonstrator sees what a person in
the VR scene sees: where the robot's end effector, the object and the target are at the start of
the episode (:func:`scene_from_env`, the one place scene positions come from). Every motion is
planned once, open loop, like a person acting on what they see, with generous pauses for the
robot to catch up; the one look after the start is a tile's set-down onto its pad (``place``),
done by eye (:mod:`.look`).

How a motion is made:

1. Waypoints for the robot's TCP (cup centre / point between the fingers) in the robot Base frame,
   tool pointing straight down, with the gesture to show at each (paper §3.2, Table 1). Where the
   task asks for it (``place``) the wrist turns the tool about the vertical: the suction head
   square to the tile on the way over it, the held tile square to its pad over the carry.
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

Here: the episodes and their hand logs (:class:`SynthEpisode`, :func:`synth_episode`,
:func:`synth_hands`); :mod:`.motion`, how the person moves (steps 2-3); :mod:`.scene`, what the
person sees and the hand pose for a tool0 pose (steps 1 and 4); :mod:`.look`, the look before
a set-down by eye.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import kin
from mimicrete.hands import layouts
from mimicrete.hands import log as handlog
from mimicrete.kin import Calibration

from .look import BY_EYE, EYE_DEG, EYE_MM, Seer
from .motion import (  # noqa: F401  (re-exported: the demonstrator's public names)
    TASKS,
    Person,
    _slow_noise,
    _tremor,
    check_task,
    min_jerk,
    plan_task,
    tracked_hand,
)
from .scene import (  # noqa: F401  (re-exported: the demonstrator's public names)
    HAND_RATE_HZ,
    SHAPE_OF,
    TOOL_DOWN,
    Scene,
    _rot_batch,
    hand_pose_for_tool0,
    have_simulator,
    obs_layout,
    points_from_base,
    scene_from_env,
    scene_from_obs,
)


@dataclass
class SynthEpisode:
    """One synthesised demonstration: frames in headset space and what made them."""

    header: dict[str, Any]
    t: np.ndarray  # (T,)
    tracked: np.ndarray  # (T,) bool
    joints: np.ndarray  # (T, N, 3) in the header's layout and space
    phases: list[str]
    tool0: np.ndarray  # (T, 4, 4) the tool0 pose each frame is meant to command (Base)
    #: the gesture class (paper Table 1) the person shows each frame: while a gesture changes
    #: through in-between shapes, the old class until the half-way shape and the new one from
    #: it on (one-frame tracking glitches keep the class the person is showing)
    gestures: list[str] = field(default_factory=list)
    #: (T,) bool: the frame is part of a change of gesture (in-between finger shapes)
    changing: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))


def synth_episode(
    scene: Scene,
    seed: int,
    *,
    layout: str = "openxr",
    calib: Calibration | None = None,
    handedness: str = "right",
    extra: dict[str, Any] | None = None,
    task_file: str | None = None,
    see: Seer | None = None,
) -> SynthEpisode:
    """Synthesise one demonstration of ``scene``; the same ``(scene, seed)`` gives the same
    episode. ``extra``: more header fields (the task spec file a scene came from);
    ``task_file``: the task spec file the scene is an episode of (where a look runs, :mod:`.look`;
    None: the task's built-in spec); ``see``: what the person sees when it looks
    (:data:`.look.Seer`; None: a task set down by eye is set down without looking)."""
    layout = layouts.check_layout(layout)
    calib = calib or Calibration()
    rng = np.random.default_rng([seed, scene.episode_seed & 0xFFFFFFFF, 0x5E17])
    person = Person.draw(rng, handedness)
    # the person's speed, tremor and sway are the hand's (headset metres); the tool's are the
    # calibration's scale times them (a task spec's hand scale: 1 on the UR3)
    k = float(calib.scale)
    tool = replace(
        person, speed=k * person.speed, tremor_mm=k * person.tremor_mm, sway_mm=k * person.sway_mm
    )
    motion = plan_task(scene, rng, tool)
    tcp, shapes, phases, transport = motion.arrays()
    turn = motion.yaws()
    gestures, changing = motion.gestures()
    n = len(tcp)
    dt = 1.0 / HAND_RATE_HZ
    tcp = tcp + _tremor(n, dt, rng, tool)
    # tool orientation: straight down, turned as planned, with a slight slow wobble (< ~1°) and
    # a personal yaw bias
    wob = np.radians(0.5) * _slow_noise(n, dt, rng, tau=0.6)
    yaw0 = rng.uniform(-0.05, 0.05)
    t = np.arange(n) * dt
    rot = (
        _rot_batch(2, yaw0 + turn + wob[:, 2]) @ _rot_batch(0, wob[:, 0]) @ _rot_batch(1, wob[:, 1])
    ) @ TOOL_DOWN
    frames = np.zeros((n, 4, 4))
    frames[:, :3, :3] = rot
    frames[:, :3, 3] = tcp - rot[:, :, 2] * scene.tcp_z  # tool z points down, to the TCP
    frames[:, 3, 3] = 1.0
    hand_rot, wrist = hand_pose_for_tool0(frames, handedness, calib)
    joints = tracked_hand(shapes, hand_rot, wrist, person, rng)
    tracked = np.ones(n, dtype=bool)
    moving = np.flatnonzero(transport)
    if len(moving) > 20 and rng.random() < 0.5:  # a short tracking dropout while moving
        k0 = int(moving[rng.integers(len(moving) - 12)])
        length = int(rng.integers(3, 12))
        tracked[k0 : k0 + length] = False
        joints[k0 : k0 + length] = joints[k0 - 1]  # the runtime repeats its last estimate
    out = layouts.to_layout(joints, layout)
    look = None
    if scene.task in BY_EYE and see is not None:
        look = _set_down_by_eye(
            scene, phases, t, tracked, out, frames, layout, handedness, calib, rng, see, task_file
        )
    header = handlog.header(
        layout,
        calib.space,
        handedness,
        task=scene.task,
        episode_seed=int(scene.episode_seed),
        source="mimicrete synth-hands (scripted demonstrator)",
        extra={
            "synth_seed": int(seed),
            "calibration": calib.to_dict(),
            "scene": scene.to_dict(),
            "person": {
                "speed_m_s": round(person.speed, 4),
                "hand_scale": round(person.hand_scale, 4),
                "tremor_mm": round(person.tremor_mm, 3),
            },
            "rate_hz": HAND_RATE_HZ,
            **({"look": look} if look is not None else {}),
            **(extra or {}),
        },
    )
    return SynthEpisode(header, t, tracked, out, phases, frames, gestures, changing)


def _set_down_by_eye(
    scene: Scene,
    phases: list[str],
    t: np.ndarray,
    tracked: np.ndarray,
    joints: np.ndarray,
    frames: np.ndarray,
    layout: str,
    handedness: str,
    calib: Calibration,
    rng: np.random.Generator,
    see: Seer,
    task_file: str | None = None,
) -> dict[str, Any]:
    """The person looks at the held object as the set-down starts (``see``,
    judged to within :data:`.look.EYE_MM` and :data:`.look.EYE_DEG`: drawn from ``rng``) and,
    while setting it down, moves the hand by the object's offset from its target and turns it
    about the TCP by the object's turn from square (min-jerk over the set-down, kept after it):
    ``joints`` (headset space) and ``frames`` (tool0, Base) change in place. Returns what the
    header records: the frame of the look and what it saw (mm, degrees)."""
    down = np.flatnonzero(np.asarray(phases) == BY_EYE[scene.task])
    k = int(down[0])
    eye = rng.normal(scale=[EYE_MM / 1000.0, EYE_MM / 1000.0, np.radians(EYE_DEG)])
    seen = eye + see(
        scene.task,
        scene.episode_seed,
        t[:k],
        tracked[:k],
        joints[:k],
        layout,
        handedness,
        calib,
        task_file,
    )
    w = np.zeros(len(t))
    w[down] = min_jerk(np.arange(1, len(down) + 1) / len(down))
    w[down[-1] + 1 :] = 1.0
    at = np.flatnonzero(w)
    tcp = frames[at, :3, 3] + frames[at, :3, 2] * scene.tcp_z  # the planned TCP (Base)
    turn = _rot_batch(2, w[at] * seen[2])
    shift = w[at, None] * np.array([seen[0], seen[1], 0.0])

    def moved(p: np.ndarray) -> np.ndarray:  # (m, j, 3) Base: turned about the TCP, shifted
        return np.einsum("mij,mkj->mki", turn, p - tcp[:, None]) + (tcp + shift)[:, None]

    shape = joints[at].shape
    base = kin.points_to_base(joints[at].reshape(-1, 3), calib).reshape(shape)
    joints[at] = points_from_base(moved(base), calib)
    frames[at, :3, 3] = moved(frames[at, None, :3, 3])[:, 0]
    frames[at, :3, :3] = turn @ frames[at, :3, :3]
    return {
        "frame": k,
        "target_minus_object_mm": np.round(1000 * seen[:2], 2).tolist(),
        "turn_to_square_deg": round(float(np.degrees(seen[2])), 3),
    }


def write_handlog(path: str | Path, ep: SynthEpisode) -> Path:
    """Write a :class:`SynthEpisode` as a hand log (JSON Lines, coordinates rounded to 10 µm)."""
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
    task_file: str | Path | None = None,
    see: Seer | None = None,
) -> list[Path]:
    """Write ``episodes`` hand logs for ``task`` into ``out``; returns their paths.

    ``scene_fn(task, episode_seed) -> Scene`` defaults to :func:`scene_from_env`; with
    ``task_file`` (a task spec file running ``task``'s logic) the scenes are that spec's episode
    starts, each header names the file and the spec (``task_file``, ``task_spec``), and the hands
    map to Base through ur3-kin's default calibration scaled by the spec's hand scale
    (:func:`mimicrete.teleop.view.task_calibration`; the same numbers on a UR3 spec).
    A task the person does not demonstrate is refused (:func:`check_task`); the row's person
    installs its tiles one after another.
    """
    check_task(task)
    extra: dict[str, Any] | None = None
    calib: Calibration | None = None
    if task_file is not None:
        from mimicrete import _native
        from mimicrete.teleop.view import task_calibration

        spec_path = str(task_file)
        extra = {"task_file": spec_path, "task_spec": _native.load_task_spec(spec_path)}
        # a person at human scale: ur3-kin's default calibration scaled by the spec's hand
        # scale (1 on the UR3), so the hands move the UR3-size distances on a larger arm
        calib = task_calibration(task, spec_path, Calibration())
        if scene_fn is None:

            def scene_fn(task: str, seed: int) -> Scene:
                return scene_from_env(task, seed, spec_path)

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
        ep = synth_episode(
            scene,
            seed * 1_000_003 + i,
            layout=layout,
            calib=calib,
            handedness=handedness,
            extra=extra,
            task_file=None if task_file is None else str(task_file),
            see=see,
        )
        paths.append(write_handlog(out / f"{task}_{i:04d}.handlog.jsonl", ep))
    return paths
