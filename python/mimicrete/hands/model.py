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
MCP 85°, PIP 105°, DIP 70°), a spread (abduction) in ``[0, 1]``, two thumb parameters: curl
(flexion of its MCP and IP joints) and opposition (0: thumb out to the side in the palm plane,
1: across the palm), a pinch (the thumb's chain solved so its tip meets the index tip) and how
much of the index's bend is at the knuckle alone (a pad-to-pad pinch bends the index there).
:data:`GESTURE_SHAPES` names the gestures and documents what each looks like;
:data:`GESTURE_RANGES` says every way of making each that the built-in training hands are drawn
from. A hand's proportions (finger and thumb lengths, where the thumb's base sits) can vary too
(:func:`random_anatomy`), as people's and tracking skeletons' do.
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
        pinch: how far the thumb has gone to the index fingertip (0: where ``thumb_curl`` and
            ``thumb_opposition`` put it, 1: thumb tip on the index tip, its chain solved to
            reach it; in between, the thumb's joints part-way).
        index_flat: share of the index's PIP and DIP flexion held back (0: the index bends like
            the other fingers, 1: it bends at the knuckle only, as in a pad-to-pad pinch).
    """

    curl: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    thumb_curl: float = 0.0
    thumb_opposition: float = 0.0
    spread: float = 0.3
    pinch: float = 0.0
    index_flat: float = 0.0

    def as_array(self) -> np.ndarray:
        """The :data:`N_SHAPE` numbers ``[curl×4, thumb_curl, thumb_opposition, spread, pinch,
        index_flat]``."""
        return np.array(
            [
                *self.curl,
                self.thumb_curl,
                self.thumb_opposition,
                self.spread,
                self.pinch,
                self.index_flat,
            ]
        )

    @staticmethod
    def from_array(a: np.ndarray) -> HandShape:
        """Inverse of :meth:`as_array` (values are clipped to ``[0, 1]``; 7 numbers, the shape
        without ``pinch`` and ``index_flat``, are read as those two at 0)."""
        a = _shape_rows(a)[0]
        return HandShape(
            curl=(float(a[0]), float(a[1]), float(a[2]), float(a[3])),
            thumb_curl=float(a[4]),
            thumb_opposition=float(a[5]),
            spread=float(a[6]),
            pinch=float(a[7]),
            index_flat=float(a[8]),
        )

    def lerp(self, other: HandShape, w: float) -> HandShape:
        """Blend toward ``other`` (``w = 0`` self, ``w = 1`` other): the in-between shapes a hand
        passes through when it changes gesture."""
        return HandShape.from_array((1.0 - w) * self.as_array() + w * other.as_array())


#: Numbers per shape (:meth:`HandShape.as_array`).
N_SHAPE = 9


def _shape_rows(params: np.ndarray) -> np.ndarray:
    """Shape rows ``(B, N_SHAPE)`` clipped to ``[0, 1]`` from ``(…, 9)`` or old ``(…, 7)``."""
    p = np.asarray(params, dtype=np.float64)
    if p.shape[-1] == 7:
        p = np.concatenate([p, np.zeros(p.shape[:-1] + (2,))], axis=-1)
    if p.shape[-1] != N_SHAPE:
        raise ValueError(f"a hand shape has {N_SHAPE} (or 7) numbers, got {p.shape[-1]}")
    return np.clip(p.reshape(-1, N_SHAPE), 0.0, 1.0)


#: The gestures as finger shapes (typical ones: what the scripted demonstrator shows and what
#: :data:`GESTURE_RANGES` spreads around). The paper shows its gestures only in its Fig. 2/3;
#: these are our choices, made from shapes a headset's hand tracking reads reliably and that
#: differ in finger configuration (the classifier sees the hand in its own frame, so a gesture
#: cannot be told from another by wrist rotation alone):
#:
#: * ``closing`` — a pinch: thumb tip on the index tip, the other fingers loose (suction on /
#:   gripper close). Meta's hand interactions select with this pinch, so a Quest tracks it well
#:   (thumb and index tips in view).
#: * ``opening`` — the open hand, relaxed or spread, thumb away from the index (drop / gripper
#:   open): the hand's resting shape, every finger in view.
#: * ``fixed`` — pointing: index straight, the other fingers curled, thumb beside them (hold the
#:   current end-effector state).
#: * ``tightening`` — the pinch with the other three fingers curled (the gripping half of the
#:   tuple is the pinch, the screwing half the closed fingers).
#: * ``loosening`` — the pinch with middle and ring curled and the little finger straight.
#: * ``fist`` — every finger curled, the thumb over the middle phalanges: no class of the shipped
#:   models (it was ``closing`` before they learnt the pinch); the left hand's discard gesture.
GESTURE_SHAPES: dict[str, HandShape] = {
    "closing": HandShape(
        curl=(0.65, 0.2, 0.2, 0.25),
        thumb_curl=0.3,
        thumb_opposition=0.6,
        spread=0.3,
        pinch=1.0,
        index_flat=0.6,
    ),
    "opening": HandShape(
        curl=(0.1, 0.1, 0.12, 0.15), thumb_curl=0.15, thumb_opposition=0.2, spread=0.5
    ),
    "fixed": HandShape(
        curl=(0.05, 0.82, 0.85, 0.85), thumb_curl=0.35, thumb_opposition=0.5, spread=0.15
    ),
    "tightening": HandShape(
        curl=(0.65, 0.88, 0.9, 0.9),
        thumb_curl=0.3,
        thumb_opposition=0.6,
        spread=0.1,
        pinch=1.0,
        index_flat=0.6,
    ),
    "loosening": HandShape(
        curl=(0.65, 0.88, 0.9, 0.08),
        thumb_curl=0.3,
        thumb_opposition=0.6,
        spread=0.3,
        pinch=1.0,
        index_flat=0.6,
    ),
    "fist": HandShape(
        curl=(0.95, 0.97, 0.97, 0.95), thumb_curl=0.75, thumb_opposition=0.85, spread=0.05
    ),
}


def _ranges(**kw: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    names = ("index", "middle", "ring", "little", "thumb_curl", "thumb_opposition", "spread")
    names += ("pinch", "index_flat")
    lo, hi = np.zeros(N_SHAPE), np.ones(N_SHAPE)
    for k, name in enumerate(names):
        lo[k], hi[k] = kw.get(name, (0.0, 1.0))
    return lo, hi


_LOOSE = (0.0, 0.45)
_CURLED = (0.7, 1.0)
#: Every way a person may form each gesture: uniform ranges ``(low, high)`` of the shape numbers
#: (:meth:`HandShape.as_array` order) the built-in training hands are drawn from
#: (:func:`sample_shape`). Wide on purpose: any pinch (index bent 40-90 % at the knuckle or
#: evenly, thumb from any start), any open hand (flat, relaxed, spread or not), any point.
#: the index and thumb of every pinch (closing, and the screwing gestures' grip)
_PINCH = dict(
    index=(0.4, 0.9),
    thumb_curl=(0.0, 0.7),
    thumb_opposition=(0.3, 1.0),
    pinch=(0.85, 1.0),
    index_flat=(0.0, 0.9),
)
GESTURE_RANGES: dict[str, tuple[np.ndarray, np.ndarray]] = {
    "closing": _ranges(**_PINCH, middle=_LOOSE, ring=_LOOSE, little=_LOOSE, spread=(0.0, 0.8)),
    "tightening": _ranges(
        **_PINCH, middle=_CURLED, ring=_CURLED, little=_CURLED, spread=(0.0, 0.5)
    ),
    "loosening": _ranges(
        **_PINCH, middle=_CURLED, ring=_CURLED, little=(0.0, 0.3), spread=(0.0, 0.8)
    ),
    "opening": _ranges(
        index=(0.0, 0.35),
        middle=(0.0, 0.35),
        ring=(0.0, 0.35),
        little=(0.0, 0.35),
        thumb_curl=(0.0, 0.5),
        thumb_opposition=(0.0, 0.6),
        pinch=(0.0, 0.15),
    ),
    "fixed": _ranges(
        index=(0.0, 0.25),
        middle=(0.6, 1.0),
        ring=(0.6, 1.0),
        little=(0.6, 1.0),
        thumb_curl=(0.0, 0.8),
        thumb_opposition=(0.0, 0.95),
        spread=(0.0, 0.5),
        pinch=(0.0, 0.1),
    ),
}


def sample_shape(name: str, rng: np.random.Generator) -> HandShape:
    """A random way of making gesture ``name``: uniform in :data:`GESTURE_RANGES`."""
    lo, hi = GESTURE_RANGES[name]
    return HandShape.from_array(rng.uniform(lo, hi))


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

#: Per-hand anatomy (:func:`random_anatomy`), numbers in this order: relative length change of
#: the index, middle, ring and little fingers' phalanges (4) and of the thumb's bones (1), the
#: thumb CMC's offset in metres (3), the tilt of the thumb's out-to-the-side direction out of the
#: palm plane in radians (1), and where a pinching thumb tip sits from the index tip, metres (3).
#: All zero: the average hand above.
N_ANATOMY = 12
#: Standard deviations of :func:`random_anatomy` (people differ by about this much; tracking
#: skeletons also place the thumb's base differently).
ANATOMY_SD = np.array([0.06] * 4 + [0.08] + [0.006] * 3 + [0.25] + [0.004] * 3)


def random_anatomy(rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """Random hand anatomies ``(N_ANATOMY,)`` or ``(n, N_ANATOMY)``: Gaussian,
    :data:`ANATOMY_SD`."""
    size = (N_ANATOMY,) if n is None else (n, N_ANATOMY)
    return rng.normal(size=size) * ANATOMY_SD


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def hand_joints_local(
    shape: HandShape,
    scale: float = 1.0,
    handedness: str = "right",
    anatomy: np.ndarray | None = None,
) -> np.ndarray:
    """The 26 OpenXR joints ``(26, 3)`` of a hand in its own frame ``H`` (see module doc).

    Args:
        shape: finger configuration.
        scale: hand size relative to an average adult hand (0.85 small … 1.15 large).
        handedness: ``"right"`` or ``"left"`` (the left hand is the mirror image, ``z → −z``).
        anatomy: ``(N_ANATOMY,)`` this hand's proportions (:func:`random_anatomy`; None: the
            average hand).
    """
    anat = None if anatomy is None else np.asarray(anatomy)[None]
    return hand_joints_local_batch(shape.as_array()[None], scale, handedness, anat)[0]


def _unit_rows(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _thumb_chain(
    tc: np.ndarray, meta_dir: np.ndarray, cmc: np.ndarray, lens: np.ndarray
) -> np.ndarray:
    """Thumb proximal, distal and tip joints ``(B, 3, 3)`` for curl ``tc (B,)``, metacarpal
    direction ``(B, 3)``, CMC ``(B, 3)`` and bone lengths ``(B, 3)``."""
    # The thumb bends toward the little finger and the palm.
    bend_goal = _unit(np.array([0.75, 0.15, -0.65]))
    bend = _unit_rows(bend_goal - (meta_dir @ bend_goal)[:, None] * meta_dir)
    out = np.empty((len(tc), 3, 3))
    out[:, 0] = cmc + lens[:, :1] * meta_dir
    theta = np.cumsum(np.radians(np.stack([10.0 + 50.0 * tc, 5.0 + 75.0 * tc], axis=1)), axis=1)
    for k in range(2):
        d = np.cos(theta[:, k, None]) * meta_dir + np.sin(theta[:, k, None]) * bend
        out[:, 1 + k] = out[:, k] + lens[:, 1 + k, None] * d
    return out


def _thumb_meta_dir(o: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Thumb metacarpal directions ``(B, 3)`` for opposition ``o`` and side tilt (radians)."""
    side0 = _unit(np.array([-0.78, 0.55, -0.30]))
    c, s = np.cos(tilt), np.sin(tilt)  # tilt the side direction about the hand's y axis
    side = np.stack(
        [c * side0[0] + s * side0[2], np.full_like(c, side0[1]), -s * side0[0] + c * side0[2]],
        axis=-1,
    )
    across = _unit(np.array([-0.05, 0.62, -0.78]))
    return _unit_rows((1.0 - o)[:, None] * side + o[:, None] * across)


def _rotate_about(points: np.ndarray, centre: np.ndarray, u: np.ndarray, v: np.ndarray):
    """Rotate ``points (B, K, 3)`` about ``centre (B, 3)`` by the smallest rotation taking unit
    ``u (B, 3)`` onto unit ``v (B, 3)``."""
    axis = np.cross(u, v)
    sin = np.linalg.norm(axis, axis=-1)
    cos = np.einsum("bi,bi->b", u, v)
    k = axis / np.maximum(sin, 1e-12)[:, None]
    p = points - centre[:, None]
    kxp = np.cross(k[:, None], p)
    kdp = np.einsum("bi,bki->bk", k, p)
    rot = (
        p * cos[:, None, None]
        + kxp * sin[:, None, None]
        + k[:, None] * (kdp * (1.0 - cos)[:, None])[..., None]
    )
    return rot + centre[:, None]


def _pinched_thumb(
    target: np.ndarray, cmc: np.ndarray, lens: np.ndarray, tilt: np.ndarray
) -> np.ndarray:
    """A thumb chain ``(B, 3, 3)`` whose tip is on ``target (B, 3)`` (or as close as it
    reaches): for each opposition of a small grid the curl that gives the right reach
    (bisection), then the opposition that needs the smallest swing of the whole thumb about its
    CMC to point the tip at the target, and that swing."""
    b = len(target)
    want = target - cmc
    reach = np.linalg.norm(want, axis=-1)
    want_dir = want / np.maximum(reach, 1e-12)[:, None]
    best = np.full(b, np.inf)
    chain = np.zeros((b, 3, 3))
    for o in np.linspace(0.2, 1.0, 5):
        md = _thumb_meta_dir(np.full(b, o), tilt)
        lo, hi = np.zeros(b), np.ones(b)  # reach shrinks as the curl grows
        for _ in range(18):
            mid = 0.5 * (lo + hi)
            r = np.linalg.norm(_thumb_chain(mid, md, cmc, lens)[:, 2] - cmc, axis=-1)
            far = r > reach
            lo, hi = np.where(far, mid, lo), np.where(far, hi, mid)
        c = _thumb_chain(0.5 * (lo + hi), md, cmc, lens)
        tip_dir = _unit_rows(c[:, 2] - cmc)
        angle = np.arccos(np.clip(np.einsum("bi,bi->b", tip_dir, want_dir), -1.0, 1.0))
        better = angle < best
        best = np.where(better, angle, best)
        rotated = _rotate_about(c, cmc, tip_dir, want_dir)
        chain[better] = rotated[better]
    return chain


def hand_joints_local_batch(
    params: np.ndarray,
    scale: float = 1.0,
    handedness: str = "right",
    anatomy: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`hand_joints_local` for a batch of shapes ``(B, N_SHAPE)`` (:meth:`HandShape.as_array`
    rows; 7-number rows are shapes without pinch) → ``(B, 26, 3)``; ``anatomy`` ``(B,
    N_ANATOMY)`` or ``(N_ANATOMY,)`` (None: the average hand)."""
    if handedness not in ("left", "right"):
        raise ValueError(f"handedness must be 'left' or 'right', got {handedness!r}")
    p = _shape_rows(params)
    b = p.shape[0]
    a = np.zeros((b, N_ANATOMY)) if anatomy is None else np.broadcast_to(anatomy, (b, N_ANATOMY))
    j = np.zeros((b, 26, 3))
    j[:, 0] = _PALM_OFFSET
    curl, tc, o, spread = p[:, :4], p[:, 4], p[:, 5], p[:, 6]
    pinch, index_flat = p[:, 7], p[:, 8]
    down = np.array([0.0, 0.0, -1.0])
    for f in range(4):
        base = 6 + 5 * f
        j[:, base] = _META_BASE[f]
        j[:, base + 1] = _MCP[f]
        ang = _REST_ANGLE[f] + spread * _SPREAD_ANGLE[f] * (1.0 - 0.7 * curl[:, f])
        rest = np.stack([np.sin(ang), np.cos(ang), np.zeros(b)], axis=-1)  # (B, 3)
        # Full-curl flexion per joint plus a slight natural flexion even when "straight".
        flex = curl[:, f, None] * _FULL_FLEX + np.radians([4.0, 5.0, 3.0])
        if f == 0:
            flex[:, 1:] *= (1.0 - index_flat)[:, None]
        theta = np.cumsum(flex, axis=1)  # (B, 3)
        d = np.cos(theta)[..., None] * rest[:, None] + np.sin(theta)[..., None] * down
        lens = _PHALANX[f][None, :, None] * (1.0 + a[:, f, None, None])
        j[:, base + 2 : base + 5] = _MCP[f] + np.cumsum(lens * d, axis=1)
    # Thumb: metacarpal direction swings from out-to-the-side (opposition 0) to across the palm.
    cmc = _THUMB_CMC + a[:, 5:8]
    tlen = _THUMB_LEN[None] * (1.0 + a[:, 4:5])
    tilt = a[:, 8]
    j[:, 2] = cmc
    j[:, 3:6] = _thumb_chain(tc, _thumb_meta_dir(o, tilt), cmc, tlen)
    pinching = pinch > 0.0
    if pinching.any():
        target = j[pinching, 10] + a[pinching, 9:12]
        reach = _pinched_thumb(target, cmc[pinching], tlen[pinching], tilt[pinching])
        w = pinch[pinching, None, None]
        j[pinching, 3:6] = (1.0 - w) * j[pinching, 3:6] + w * reach
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
    anatomy: np.ndarray | None = None,
) -> np.ndarray:
    """The 26 OpenXR joints ``(26, 3)`` in the tracking space.

    Args:
        shape: finger configuration.
        wrist_rot: ``(3, 3)`` rotation whose columns are the hand frame's X, Y, Z axes (the
            paper's frame, see the module doc) expressed in the tracking space.
        wrist_pos: ``(3,)`` wrist position in the tracking space, metres.
        scale: hand size factor.
        handedness: ``"right"`` or ``"left"``.
        anatomy: this hand's proportions (:func:`random_anatomy`; None: the average hand).
    """
    local = hand_joints_local(shape, scale, handedness, anatomy)
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
    return HandShape.from_array(shape.as_array() + rng.normal(scale=sd, size=N_SHAPE))


__all__ = [
    "ANATOMY_SD",
    "GESTURE_RANGES",
    "GESTURE_SHAPES",
    "N_ANATOMY",
    "N_SHAPE",
    "HandShape",
    "hand_frame",
    "hand_joints",
    "hand_joints_local",
    "hand_joints_local_batch",
    "jitter_shape",
    "random_anatomy",
    "random_rotation",
    "sample_shape",
    "rotation_matrix",
    "tracking_noise",
    "tracking_noise_batch",
]
