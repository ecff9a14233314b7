"""UR kinematics (the Rust crate ``ur3-kin`` through ``mimicrete._native``).

Frames and units: every pose is a homogeneous ``(4, 4)`` float64 matrix of ``tool0`` (the flange,
zero TCP) in the UR controller's *Base* frame (DH frame 0, Z up), metres; joint angles are radians,
base to wrist 3. Models: ``ur3``, ``ur3e``, ``ur5``, ``ur5e``, ``ur10``, ``ur10e``.

Errors: :class:`mimicrete.IkError` when a pose is unreachable or the solver does not converge;
``ValueError`` for bad shapes (the message names the expected shape), unknown names, NaN/inf and
matrices that are not rigid transforms.

Hand → target (paper §3.2): origin at the wrist, ``y`` = wrist → middle-proximal, ``z`` =
``x' × y`` with ``x'`` = index-proximal → middle-proximal (mirrored for the left hand so both hands
give the dorsal normal), ``x = y × z``. tool0 gets ``x = hand y`` (along the fingers) and
``z = −hand z`` (out of the palm): a palm-down hand reaching forward gives a tool pointing down.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mimicrete import _native

__all__ = [
    "MODELS",
    "Calibration",
    "calibration_parts",
    "dh",
    "fk",
    "fk_all",
    "fk_batch",
    "hand_to_target",
    "hand_to_target_batch",
    "ik",
    "ik_all",
    "ik_batch",
    "ik_gn",
    "jacobian",
    "parse_calibration",
    "points_to_base",
    "quat_matrix",
    "urdf",
]

MODELS: tuple[str, ...] = tuple(_native.kin_models())
#: The spaces a stored calibration (:func:`parse_calibration`) may name.
SPACES: tuple[str, ...] = ("openxr", "webxr", "unity", "robot_base")


def _arr(x: Any, name: str) -> np.ndarray:
    try:
        a = np.ascontiguousarray(x, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name} must be numeric: {e}") from None
    return a


def _shaped(x: Any, name: str, shape: tuple[int | None, ...], text: str) -> np.ndarray:
    a = _arr(x, name)
    if a.ndim != len(shape) or any(
        s is not None and s != d for s, d in zip(shape, a.shape, strict=True)
    ):
        raise ValueError(f"{name} must have shape {text}, got {a.shape}")
    return a


def quat_matrix(q: Any) -> np.ndarray:
    """The (3, 3) rotation matrix of a unit quaternion ``[x, y, z, w]`` (the order the simulator's
    snapshots and scene items give)."""
    x, y, z, w = (float(v) for v in q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def dh(model: str = "ur3") -> dict[str, float]:
    """The model's DH numbers ``d1, a2, a3, d4, d5, d6`` and an upper bound of its ``reach`` (m)."""
    return dict(_native.kin_dh(model))


def fk(q: Any, model: str = "ur3") -> np.ndarray:
    """Forward kinematics: joint angles ``(6,)`` → tool0 in Base ``(4, 4)``."""
    return _native.kin_fk(_shaped(q, "q", (6,), "(6,)"), model)


def fk_batch(q: Any, model: str = "ur3") -> np.ndarray:
    """Forward kinematics of many configurations: ``(N, 6)`` → ``(N, 4, 4)``."""
    return _native.kin_fk_batch(_shaped(q, "q", (None, 6), "(N, 6)"), model)


def fk_all(q: Any, model: str = "ur3") -> np.ndarray:
    """Every DH frame in Base: ``(7, 4, 4)``; index 0 is Base, index ``i`` follows joint ``i``,
    index 6 is tool0."""
    return _native.kin_fk_all(_shaped(q, "q", (6,), "(6,)"), model)


def jacobian(q: Any, model: str = "ur3") -> np.ndarray:
    """Geometric Jacobian of tool0 in Base, ``(6, 6)``: rows linear velocity (m/s) then angular
    velocity (rad/s); column ``i`` is joint ``i + 1``."""
    return _native.kin_jacobian(_shaped(q, "q", (6,), "(6,)"), model)


def ik(T: Any, seed: Any = None, model: str = "ur3", tol: float | None = None) -> np.ndarray:
    """Inverse kinematics: tool0 pose ``(4, 4)`` → joint angles ``(6,)`` wrapped to [-π, π].

    Returns the solution nearest ``seed`` (per-joint wrapped distance); without a seed, the one
    nearest the zero configuration. Gauss-Newton from the seed first (the paper's Table 2 solver),
    the closed-form branches as cold-start seeds and fallback, every answer polished to ``tol``
    (default 1e-10 m and rad).

    Raises:
        mimicrete.IkError: the pose is unreachable or no candidate converged.
        ValueError: bad shape, NaN/inf, or ``T`` is not a rigid transform.
    """
    t = _shaped(T, "T", (4, 4), "(4, 4)")
    s = None if seed is None else _shaped(seed, "seed", (6,), "(6,)")
    return _native.kin_ik(t, s, model, tol)


def ik_gn(
    T: Any, seed: Any, model: str = "ur3", tol: float | None = None, max_iters: int = 100
) -> np.ndarray:
    """The paper's Gauss-Newton alone (no closed form): from ``seed`` ``(6,)``, full steps
    ``J⁻¹e`` (SVD pseudo-inverse when ``J`` is near singular), angles wrapped every step.

    Raises:
        mimicrete.IkError: not converged within ``max_iters``.
    """
    t = _shaped(T, "T", (4, 4), "(4, 4)")
    return _native.kin_ik_gn(t, _shaped(seed, "seed", (6,), "(6,)"), model, tol, int(max_iters))


def ik_all(T: Any, model: str = "ur3", q6_ref: float = 0.0) -> np.ndarray:
    """Every closed-form solution that reproduces ``T``: ``(k, 6)``, ``0 ≤ k ≤ 8`` (``k = 0`` when
    unreachable). At a wrist singularity (sin q5 ≈ 0) q6 is ``q6_ref``."""
    return _native.kin_ik_all(_shaped(T, "T", (4, 4), "(4, 4)"), model, float(q6_ref))


def ik_batch(
    Ts: Any, seeds: Any = None, model: str = "ur3", threads: int = 0, tol: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Batched :func:`ik` over native threads (the GIL is released).

    Args:
        Ts: ``(N, 4, 4)`` target poses.
        seeds: ``(N, 6)`` or ``None``.
        threads: worker threads (0 = all cores).

    Returns:
        ``(q, ok)``: ``q`` ``(N, 6)`` with NaN rows where ``ok`` ``(N,)`` is False (unreachable,
        not converged, or not a rigid transform).
    """
    t = _shaped(Ts, "Ts", (None, 4, 4), "(N, 4, 4)")
    s = None
    if seeds is not None:
        s = _shaped(seeds, "seeds", (t.shape[0], 6), f"({t.shape[0]}, 6) to match Ts")
    return _native.kin_ik_batch(t, s, model, int(threads), tol)


def _default_calibration() -> tuple[np.ndarray, float, str]:
    """ur3-kin's ``Calibration::default()``: ``base_from_space`` (4, 4), scale, space name."""
    m, scale, space = _native.kin_default_calibration()
    return np.asarray(m, dtype=np.float64), float(scale), str(space)


_DEFAULT_BASE_FROM_SPACE, _DEFAULT_SCALE, _DEFAULT_SPACE = _default_calibration()


@dataclass
class Calibration:
    """Tracking space → robot Base: ``p_base = rotation · (scale · to_flu(p)) + translation``.

    ``to_flu`` is the fixed axis change of ``space`` to right-handed Z-up axes (forward, left, up):
    OpenXR/WebXR ``(−z, −x, y)``, Unity (left-handed) ``(z, −x, y)``, ``robot_base`` identity.
    The defaults are ur3-kin's ``Calibration::default()`` (read from the crate, not restated here):
    OpenXR LOCAL space, operator behind the robot facing Base +X, so a hand 0.4 m in front of and
    below the head maps to (0.3, 0, 0.2) m in Base.

    Hand-log headers store it under ``extra.calibration`` as :meth:`to_dict` gives it;
    :func:`parse_calibration` reads it back.
    """

    rotation: np.ndarray = field(default_factory=lambda: _DEFAULT_BASE_FROM_SPACE[:3, :3].copy())
    translation: np.ndarray = field(default_factory=lambda: _DEFAULT_BASE_FROM_SPACE[:3, 3].copy())
    scale: float = _DEFAULT_SCALE
    space: str = _DEFAULT_SPACE

    def __post_init__(self) -> None:
        self.rotation = np.asarray(self.rotation, dtype=np.float64).reshape(3, 3)
        self.translation = np.asarray(self.translation, dtype=np.float64).reshape(3)

    def matrix(self) -> np.ndarray:
        """``base_from_space`` as ``(4, 4)``."""
        m = np.eye(4)
        m[:3, :3] = self.rotation
        m[:3, 3] = self.translation
        return m

    def scaled(self, k: float) -> Calibration:
        """This calibration followed by scaling Base by ``k`` about its origin (the robot's base):
        ``p_base = k · (rotation · (scale · to_flu(p)) + translation)``. A hand moving as before
        moves the tool ``k`` times as far, over a scene laid out ``k`` times as large about the
        base (a task spec's hand scale: :func:`mimicrete.teleop.view.task_calibration`);
        ``k = 1`` gives the same numbers."""
        k = float(k)
        return Calibration(self.rotation.copy(), k * self.translation, k * self.scale, self.space)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form ``{rotation (3×3 lists), translation, scale, space}`` (the hand-log
        header's ``extra.calibration``)."""
        return {
            "rotation": self.rotation.tolist(),
            "translation": self.translation.tolist(),
            "scale": float(self.scale),
            "space": self.space,
        }

    @classmethod
    def from_dict(
        cls,
        d: Any,
        file: str = "calibration",
        line: int | None = None,
        field: str | None = None,
    ) -> Calibration:
        """Inverse of :meth:`to_dict`, checked: :func:`parse_calibration`."""
        return parse_calibration(d, file, line, field)


def parse_calibration(
    d: Any, file: str = "calibration", line: int | None = None, field: str | None = None
) -> Calibration:
    """A calibration from its JSON form (:meth:`Calibration.to_dict`: ``rotation`` 3×3,
    ``translation`` 3 numbers, ``scale`` > 0, ``space``), checked: the one parser of a stored
    calibration (hand-log headers' ``extra.calibration``, ``--calibration FILE``, a recentre's
    ``calibration.json``).

    Raises:
        mimicrete.LogFormatError: ``file:line: field: reason`` (``line`` None: no line;
            ``field`` None: no field) for anything that is not such a calibration.
    """

    def bad(reason: str) -> Exception:
        return _native.log_format_error(file, line, f"{field}: {reason}" if field else reason)

    if not isinstance(d, dict):
        raise bad("must be an object with rotation, translation, scale, space")
    missing = [k for k in ("rotation", "translation", "scale", "space") if k not in d]
    if missing:
        raise bad(f"missing {', '.join(missing)}")
    try:
        rot = np.asarray(d["rotation"], dtype=np.float64)
        tr = np.asarray(d["translation"], dtype=np.float64)
        scale = float(d["scale"])
    except (TypeError, ValueError) as e:
        raise bad(f"not numbers ({e})") from None
    if rot.shape != (3, 3) or tr.shape != (3,):
        raise bad(f"rotation must be 3×3 and translation 3 numbers, got {rot.shape}, {tr.shape}")
    if not (np.all(np.isfinite(rot)) and np.all(np.isfinite(tr)) and np.isfinite(scale)):
        raise bad("NaN or infinite values")
    if not scale > 0:
        raise bad(f"scale must be > 0, got {scale}")
    if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-6) or np.linalg.det(rot) < 0:
        raise bad("rotation is not a rotation matrix")
    space = d["space"]
    if space not in SPACES:
        raise bad(f"unknown space {space!r} ({', '.join(SPACES)})")
    return Calibration(rot, tr, scale, space)


def calibration_parts(c: Any) -> tuple[np.ndarray | None, float, str]:
    """A calibration as the Rust side takes it: ``(base_from_space (4, 4) or None, scale,
    space)``. Accepts None (default), a Calibration-like object (``rotation`` / ``translation`` /
    ``scale`` / ``space`` attributes, or ``base_from_space`` (4, 4)) or a dict with those keys."""
    if c is None:  # ur3-kin's default (the transform is filled in on the Rust side)
        return None, _DEFAULT_SCALE, _DEFAULT_SPACE
    get = c.get if isinstance(c, dict) else (lambda k, d=None: getattr(c, k, d))
    scale = float(get("scale", 1.0))
    space = str(get("space", "openxr"))
    m = get("base_from_space", None)
    if m is None:
        m = np.eye(4)
        rot = get("rotation", None)
        tr = get("translation", None)
        if rot is not None:
            m[:3, :3] = _shaped(rot, "calibration.rotation", (3, 3), "(3, 3)")
        if tr is not None:
            m[:3, 3] = _shaped(np.ravel(tr), "calibration.translation", (3,), "(3,)")
    return _shaped(m, "calibration.base_from_space", (4, 4), "(4, 4)"), scale, space


def _hand_call(
    native: Any,
    wrist: Any,
    index_proximal: Any,
    middle_proximal: Any,
    handedness: str,
    calibration: Any,
    batch: bool,
) -> Any:
    """Check the three joints (``(3,)`` each, or ``(N, 3)`` each with ``batch``), convert the
    calibration and call the native hand → target entry point."""
    calib = calibration_parts(calibration)
    if batch:
        w = _shaped(wrist, "wrist", (None, 3), "(N, 3)")
        shape: tuple[int | None, ...] = (w.shape[0], 3)
        text = f"({w.shape[0]}, 3)"
    else:
        shape, text = (3,), "(3,)"
        w = _shaped(wrist, "wrist", shape, text)
    return native(
        w,
        _shaped(index_proximal, "index_proximal", shape, text),
        _shaped(middle_proximal, "middle_proximal", shape, text),
        handedness,
        calib,
    )


def hand_to_target(
    wrist: Any,
    index_proximal: Any,
    middle_proximal: Any,
    handedness: str = "right",
    calibration: Any = None,
) -> np.ndarray:
    """Tracked hand joints (each ``(3,)``, in the calibration's space) → tool0 target ``(4, 4)``
    in Base (module docstring gives the axes).

    Raises:
        ValueError: degenerate hand (coincident or collinear joints), NaN/inf, bad shape.
    """
    return _hand_call(
        _native.kin_hand_to_target,
        wrist,
        index_proximal,
        middle_proximal,
        handedness,
        calibration,
        batch=False,
    )


def hand_to_target_batch(
    wrist: Any,
    index_proximal: Any,
    middle_proximal: Any,
    handedness: str = "right",
    calibration: Any = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`hand_to_target` for ``(N, 3)`` arrays: ``(T (N, 4, 4), ok (N,))``; rows with a
    degenerate or non-finite hand have ``ok`` False and an identity ``T``."""
    return _hand_call(
        _native.kin_hand_to_target_batch,
        wrist,
        index_proximal,
        middle_proximal,
        handedness,
        calibration,
        batch=True,
    )


def points_to_base(points: Any, calibration: Any = None) -> np.ndarray:
    """Points ``(3,)`` or ``(N, 3)`` from the calibration's space into Base (same shape out)."""
    p = _arr(points, "points")
    single = p.ndim == 1
    p2 = _shaped(p.reshape(1, -1) if single else p, "points", (None, 3), "(3,) or (N, 3)")
    out = _native.kin_points_to_base(p2, calibration_parts(calibration))
    return out[0] if single else out


def urdf(model: str = "ur3") -> str:
    """The model's URDF (root link ``base`` = UR Base frame, tip ``tool0``), written from its DH
    table; FK along it equals :func:`fk`."""
    return _native.kin_urdf(model)
