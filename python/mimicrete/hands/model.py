"""A parametric human hand: 3-D joint positions from a wrist pose and finger shapes.

The model builds the 26 OpenXR hand joints (``XrHandJointEXT`` order: 0 palm, 1 wrist, 2-5 thumb
metacarpal/proximal/distal/tip, then index, middle, ring, little with metacarpal, proximal,
intermediate, distal, tip) and maps them to the other layouts (WebXR 25, Meta OVR legacy 24,
MediaPipe 21; see ``docs``/reference note §4 for the orders).

Hand frame ``H`` (the frame every shape is built in, metres, before the wrist pose is applied):

* origin at the wrist joint;
* ``+Y`` points from the wrist to the middle finger's proximal joint (the MCP knuckle), which sits
  exactly on the axis, so ``H`` is the frame the paper builds from wrist / index-proximal /
  middle-proximal positions (§3.2);
* ``+X`` is the index → middle direction made orthogonal to ``+Y`` (radial → ulnar side);
* ``+Z = X × Y``. For a right hand that is the back of the hand (dorsal). A left hand is the
  mirror image of the right one through its palm plane (``z → −z`` in ``H``): with the paper's
  axes its palm faces ``+Z``. ``H`` is therefore exactly the frame :func:`hand_frame` returns
  for either hand.

Finger shapes (:class:`HandShape`) are a curl per finger in ``[0, 1]`` (0 straight, 1 a full fist:
MCP 85°, PIP 105°, DIP 70°), a spread (abduction) in ``[0, 1]``, and two thumb parameters: curl
(flexion of its MCP and IP joints) and opposition (0: thumb out to the side in the palm plane,
1: across the palm). :data:`GESTURE_SHAPES` names the gestures of paper Table 1 and documents
what each looks like.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# ----------------------------------------------------------------------------------------------
# Shapes
# ----------------------------------------------------------------------------------------------

FINGERS: tuple[str, ...] = ("index", "middle", "ring", "little")


@dataclass(frozen=True)
class HandShape:
    """Finger configuration, each value in ``[0, 1]``.

    Attributes:
        curl: flexion of index, middle, ring, little (0 straight, 1 fist).
        thumb_curl: flexion of the thumb's MCP and IP joints.
        thumb_opposition: 0 thumb out to the side, 1 thumb across the palm.
        spread: abduction of the fingers (0 together, 1 spread wide).
    """

    curl: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    thumb_curl: float = 0.0
    thumb_opposition: float = 0.0
    spread: float = 0.3

    def as_array(self) -> np.ndarray:
        """The 7 numbers ``[curl×4, thumb_curl, thumb_opposition, spread]``."""
        return np.array([*self.curl, self.thumb_curl, self.thumb_opposition, self.spread])

    @staticmethod
    def from_array(a: np.ndarray) -> HandShape:
        """Inverse of :meth:`as_array` (values are clipped to ``[0, 1]``)."""
        a = np.clip(np.asarray(a, dtype=np.float64), 0.0, 1.0)
        return HandShape(
            curl=(float(a[0]), float(a[1]), float(a[2]), float(a[3])),
            thumb_curl=float(a[4]),
            thumb_opposition=float(a[5]),
            spread=float(a[6]),
        )

    def lerp(self, other: HandShape, w: float) -> HandShape:
        """Blend toward ``other`` (``w = 0`` self, ``w = 1`` other): the in-between shapes a hand
        passes through when it changes gesture."""
        return HandShape.from_array((1.0 - w) * self.as_array() + w * other.as_array())


#: The gestures of paper Table 1 as finger shapes. The paper shows them only in its Fig. 2/3;
#: these are our choices, made so that a person can form each one quickly and they differ in
#: finger configuration (the classifier sees the hand in its own frame, so a gesture cannot be
#: told from another by wrist rotation alone):
#:
#: * ``closing`` — a fist, thumb wrapped over the middle phalanges ("grasp"; suction on /
#:   gripper close).
#: * ``opening`` — a flat open hand, fingers spread, thumb out (drop / gripper open).
#: * ``fixed`` — pointing: index straight, other fingers curled, thumb resting on the middle
#:   finger (hold the current end-effector state).
#: * ``tightening`` — a fist with the thumb straight out ("thumbs-up" fist: the right-hand rule
#:   of a screw being driven in).
#: * ``loosening`` — a fist with the little finger straight out.
GESTURE_SHAPES: dict[str, HandShape] = {
    "closing": HandShape(
        curl=(0.95, 0.97, 0.97, 0.95), thumb_curl=0.75, thumb_opposition=0.85, spread=0.05
    ),
    "opening": HandShape(
        curl=(0.03, 0.03, 0.04, 0.05), thumb_curl=0.05, thumb_opposition=0.1, spread=0.8
    ),
    "fixed": HandShape(
        curl=(0.05, 0.92, 0.95, 0.95), thumb_curl=0.55, thumb_opposition=0.8, spread=0.15
    ),
    "tightening": HandShape(
        curl=(0.95, 0.97, 0.97, 0.95), thumb_curl=0.0, thumb_opposition=0.05, spread=0.05
    ),
    "loosening": HandShape(
        curl=(0.95, 0.97, 0.97, 0.08), thumb_curl=0.75, thumb_opposition=0.85, spread=0.3
    ),
}

# ----------------------------------------------------------------------------------------------
# Geometry (right hand, frame H, hand scale 1 ≈ an adult hand of 19 cm wrist → middle tip)
# ----------------------------------------------------------------------------------------------

# Metacarpal bases (carpometacarpal joints) and proximal joints (MCP knuckles), metres.
_META_BASE = np.array(
    [[-0.012, 0.022, -0.004], [0.0, 0.024, -0.004], [0.011, 0.022, -0.005], [0.020, 0.018, -0.007]]
)
_MCP = np.array(
    [[-0.023, 0.082, 0.0], [0.0, 0.086, 0.0], [0.019, 0.080, -0.003], [0.036, 0.068, -0.007]]
)
# Phalanx lengths (proximal, intermediate, distal→tip).
_PHALANX = np.array(
    [[0.040, 0.023, 0.021], [0.045, 0.027, 0.022], [0.042, 0.026, 0.022], [0.033, 0.018, 0.020]]
)
# Rest direction angle in the palm plane (radians, + toward the little finger) at spread 0 and
# the extra angle at spread 1.
_REST_ANGLE = np.array([-0.06, 0.0, 0.05, 0.10])
_SPREAD_ANGLE = np.array([-0.22, -0.02, 0.16, 0.32])
# Full-curl flexion (radians) of MCP, PIP, DIP.
_FULL_FLEX = np.radians([85.0, 105.0, 70.0])

_THUMB_CMC = np.array([-0.020, 0.026, -0.014])
_THUMB_LEN = np.array([0.042, 0.032, 0.029])  # metacarpal, proximal, distal→tip
_PALM_OFFSET = np.array([0.0, 0.050, -0.012])  # OpenXR palm joint: centre of the palm


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def hand_joints_local(
    shape: HandShape, scale: float = 1.0, handedness: str = "right"
) -> np.ndarray:
    """The 26 OpenXR joints ``(26, 3)`` of a hand in its own frame ``H`` (see module doc).

    Args:
        shape: finger configuration.
        scale: hand size relative to an average adult hand (0.85 small … 1.15 large).
        handedness: ``"right"`` or ``"left"`` (the left hand is the mirror image, ``z → −z``).
    """
    return hand_joints_local_batch(shape.as_array()[None], scale, handedness)[0]


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def hand_joints_local_batch(
    params: np.ndarray, scale: float = 1.0, handedness: str = "right"
) -> np.ndarray:
    """:func:`hand_joints_local` for a batch of shapes ``(B, 7)`` (:meth:`HandShape.as_array`
    rows) → ``(B, 26, 3)``."""
    if handedness not in ("left", "right"):
        raise ValueError(f"handedness must be 'left' or 'right', got {handedness!r}")
    p = np.clip(np.asarray(params, dtype=np.float64).reshape(-1, 7), 0.0, 1.0)
    b = p.shape[0]
    j = np.zeros((b, 26, 3))
    j[:, 0] = _PALM_OFFSET
    curl, tc, o, spread = p[:, :4], p[:, 4], p[:, 5], p[:, 6]
    down = np.array([0.0, 0.0, -1.0])
    for f in range(4):
        base = 6 + 5 * f
        j[:, base] = _META_BASE[f]
        j[:, base + 1] = _MCP[f]
        ang = _REST_ANGLE[f] + spread * _SPREAD_ANGLE[f] * (1.0 - 0.7 * curl[:, f])
        rest = np.stack([np.sin(ang), np.cos(ang), np.zeros(b)], axis=-1)  # (B, 3)
        # Full-curl flexion per joint plus a slight natural flexion even when "straight".
        flex = curl[:, f, None] * _FULL_FLEX + np.radians([4.0, 5.0, 3.0])
        theta = np.cumsum(flex, axis=1)  # (B, 3)
        d = np.cos(theta)[..., None] * rest[:, None] + np.sin(theta)[..., None] * down
        j[:, base + 2 : base + 5] = _MCP[f] + np.cumsum(_PHALANX[f][:, None] * d, axis=1)
    # Thumb: metacarpal direction swings from out-to-the-side (opposition 0) to across the palm.
    side = _unit(np.array([-0.78, 0.55, -0.30]))
    across = _unit(np.array([-0.05, 0.62, -0.78]))
    meta_dir = _unit_rows((1.0 - o)[:, None] * side + o[:, None] * across)
    # The thumb bends toward the little finger and the palm.
    bend_goal = _unit(np.array([0.75, 0.15, -0.65]))
    bend = _unit_rows(bend_goal - (meta_dir @ bend_goal)[:, None] * meta_dir)
    j[:, 2] = _THUMB_CMC
    j[:, 3] = _THUMB_CMC + _THUMB_LEN[0] * meta_dir
    theta = np.cumsum(np.radians(np.stack([10.0 + 50.0 * tc, 5.0 + 75.0 * tc], axis=1)), axis=1)
    for k in range(2):
        d = np.cos(theta[:, k, None]) * meta_dir + np.sin(theta[:, k, None]) * bend
        j[:, 4 + k] = j[:, 3 + k] + _THUMB_LEN[1 + k] * d
    j *= scale
    if handedness == "left":
        j[..., 2] *= -1.0
    return j


def rotation_matrix(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit ``axis`` by ``angle`` radians (Rodrigues)."""
    a = _unit(np.asarray(axis, dtype=np.float64))
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random rotation matrix."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def hand_joints(
    shape: HandShape,
    wrist_rot: np.ndarray,
    wrist_pos: np.ndarray,
    scale: float = 1.0,
    handedness: str = "right",
) -> np.ndarray:
    """The 26 OpenXR joints ``(26, 3)`` in the tracking space.

    Args:
        shape: finger configuration.
        wrist_rot: ``(3, 3)`` rotation whose columns are the hand frame's X, Y, Z axes (the
            paper's frame, see the module doc) expressed in the tracking space.
        wrist_pos: ``(3,)`` wrist position in the tracking space, metres.
        scale: hand size factor.
        handedness: ``"right"`` or ``"left"``.
    """
    local = hand_joints_local(shape, scale, handedness)
    return local @ np.asarray(wrist_rot, dtype=np.float64).T + np.asarray(wrist_pos, np.float64)


def hand_frame(wrist: np.ndarray, index_proximal: np.ndarray, middle_proximal: np.ndarray):
    """The paper's hand frame from three joint positions (§3.2).

    Returns:
        ``(R, origin)``: ``R`` (3, 3) with columns x, y, z where ``y = n(mid − wrist)``,
        ``z = n((mid − idx) × y)``, ``x = y × z``; origin is the wrist. Raises ``ValueError`` for
        degenerate input (coincident or collinear joints).
    """
    w = np.asarray(wrist, dtype=np.float64)
    yv = np.asarray(middle_proximal, dtype=np.float64) - w
    xv = np.asarray(middle_proximal, dtype=np.float64) - np.asarray(index_proximal, np.float64)
    ny = np.linalg.norm(yv)
    zv = np.cross(xv, yv)
    nz = np.linalg.norm(zv)
    if ny < 1e-9 or nz < 1e-12 * max(1.0, ny * np.linalg.norm(xv)):
        raise ValueError("degenerate hand frame: wrist, index and middle proximal are collinear")
    y = yv / ny
    z = zv / nz
    x = np.cross(y, z)
    return np.column_stack([x, y, z]), w


def tracking_noise(
    joints: np.ndarray, rng: np.random.Generator, sigma: float = 0.003, occluded_sigma: float = 0.0
) -> np.ndarray:
    """Add hand-tracking noise to OpenXR joints ``(26, 3)``.

    Every joint gets isotropic Gaussian noise of ``sigma`` metres; fingertips and distal joints of
    curled fingers (hidden from the headset cameras) additionally get ``occluded_sigma`` scaled by
    how far the fingertip has come toward the palm.
    """
    j = np.asarray(joints, dtype=np.float64)
    out = j + rng.normal(scale=sigma, size=j.shape)
    if occluded_sigma > 0.0:
        span = np.linalg.norm(j[12] - j[1])
        for f in range(5):
            tip = 5 if f == 0 else 10 + 5 * (f - 1)
            closeness = np.clip(1.0 - np.linalg.norm(j[tip] - j[1]) / (2.2 * span), 0.0, 1.0)
            for k in (tip - 1, tip):
                out[k] += rng.normal(scale=occluded_sigma * closeness, size=3)
    return out


def tracking_noise_batch(
    joints: np.ndarray, rng: np.random.Generator, sigma: float = 0.003, occluded_sigma: float = 0.0
) -> np.ndarray:
    """:func:`tracking_noise` for a batch of OpenXR hands ``(B, 26, 3)``."""
    j = np.asarray(joints, dtype=np.float64)
    out = j + rng.normal(scale=sigma, size=j.shape)
    if occluded_sigma > 0.0:
        span = np.linalg.norm(j[:, 12] - j[:, 1], axis=-1)
        tips = np.array([5, 10, 15, 20, 25])
        dist = np.linalg.norm(j[:, tips] - j[:, 1:2], axis=-1)  # (B, 5)
        closeness = np.clip(1.0 - dist / (2.2 * span[:, None]), 0.0, 1.0)
        for k, tip in enumerate(tips):
            for idx in (tip - 1, tip):
                out[:, idx] += rng.normal(size=(len(j), 3)) * (
                    occluded_sigma * closeness[:, k, None]
                )
    return out


def jitter_shape(shape: HandShape, rng: np.random.Generator, sd: float = 0.06) -> HandShape:
    """A person's version of a gesture: every parameter moved by ``N(0, sd)`` (clipped)."""
    return HandShape.from_array(shape.as_array() + rng.normal(scale=sd, size=7))


__all__ = [
    "GESTURE_SHAPES",
    "HandShape",
    "hand_frame",
    "hand_joints",
    "hand_joints_local",
    "hand_joints_local_batch",
    "jitter_shape",
    "random_rotation",
    "rotation_matrix",
    "tracking_noise",
    "tracking_noise_batch",
]
