"""Gesture features: 3-D hand joints (any layout) or 2-D image landmarks → a pose-, position- and
size-invariant vector (see the package docstring)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mimicrete.hands import layouts


def features_3d(
    joints: np.ndarray, layout: str = "openxr", handedness: Any = "right"
) -> np.ndarray:
    """Pose-, position- and size-invariant features of 3-D hand joints.

    Args:
        joints: ``(N, 3)`` or ``(B, N, 3)`` joint positions in ``layout`` order.
        layout: the joint order (``openxr``, ``webxr``, ``meta_ovr``, ``mediapipe``).
        handedness: ``"left"``/``"right"`` or a ``(B,)`` array of them.

    Returns:
        ``(60,)`` or ``(B, 60)``: the 20 non-wrist canonical landmarks in the hand frame, divided
        by the wrist → middle-proximal length. Degenerate hands (collinear frame joints) give NaN.
    """
    j = np.asarray(joints, dtype=np.float64)
    single = j.ndim == 2
    if single and j.shape[-1] == 3:
        return _features_3d_one(layouts.canonical21(j, layout), handedness == "left")
    if single:
        j = j[None]
    c = layouts.canonical21(j, layout)
    if c.shape[-1] != 3:
        raise ValueError(f"features_3d needs x,y,z coordinates, got {c.shape[-1]} per joint")
    wrist = c[:, 0]
    yv = c[:, 9] - wrist
    xv = c[:, 9] - c[:, 5]
    length = np.linalg.norm(yv, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        y = yv / length
        zv = np.cross(xv, y)
        z = zv / np.linalg.norm(zv, axis=-1, keepdims=True)
        x = np.cross(y, z)
        rot = np.stack([x, y, z], axis=-1)  # (B, 3, 3), columns = axes
        rel = (c[:, 1:] - wrist[:, None]) / length[:, None]
    local = np.einsum("bnk,bkj->bnj", rel, rot)
    left = np.broadcast_to(np.asarray(handedness) == "left", (j.shape[0],))
    local[left, :, 2] *= -1.0
    out = local.reshape(j.shape[0], -1)
    return out[0] if single else out


def _features_3d_one(c: np.ndarray, left: bool) -> np.ndarray:
    """:func:`features_3d` of one hand's canonical landmarks ``(21, 3)`` (the per-frame path:
    scalar cross products, no batch machinery)."""
    w = c[0]
    yx, yy, yz = c[9] - w
    length = math.sqrt(yx * yx + yy * yy + yz * yz)
    if not length > 1e-12:
        return np.full(60, np.nan)
    yx, yy, yz = yx / length, yy / length, yz / length
    ax, ay, az = c[9] - c[5]
    zx, zy, zz = ay * yz - az * yy, az * yx - ax * yz, ax * yy - ay * yx
    nz = math.sqrt(zx * zx + zy * zy + zz * zz)
    if not nz > 1e-12:
        return np.full(60, np.nan)
    zx, zy, zz = zx / nz, zy / nz, zz / nz
    rot = np.array(
        [[yy * zz - yz * zy, yx, zx], [yz * zx - yx * zz, yy, zy], [yx * zy - yy * zx, yz, zz]]
    )
    local = ((c[1:] - w) / length) @ rot
    if left:
        local[:, 2] *= -1.0
    return local.ravel()


def features_2d(points: np.ndarray, layout: str = "mediapipe") -> np.ndarray:
    """Rotation-, position- and scale-invariant features of 2-D image landmarks.

    Args:
        points: ``(N, 2)`` or ``(B, N, 2)`` in ``layout`` order (already wrist-relative or not,
            normalised or in pixels: all the same after this).

    Returns:
        ``(40,)`` or ``(B, 40)``: the 20 non-wrist canonical landmarks relative to the wrist,
        rotated so wrist → middle MCP is ``+y``, divided by that length.
    """
    p = np.asarray(points, dtype=np.float64)
    single = p.ndim == 2
    if single:
        p = p[None]
    c = layouts.canonical21(p, layout)
    if c.shape[-1] != 2:
        raise ValueError(f"features_2d needs x,y coordinates, got {c.shape[-1]} per joint")
    rel = c[:, 1:] - c[:, :1]
    v = rel[:, 8]  # middle MCP (canonical index 9, minus the wrist)
    length = np.linalg.norm(v, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos, sin = v[:, 1] / length, v[:, 0] / length  # rotate v onto +y
        xr = cos[:, None] * rel[..., 0] - sin[:, None] * rel[..., 1]
        yr = sin[:, None] * rel[..., 0] + cos[:, None] * rel[..., 1]
        out = np.stack([xr, yr], axis=-1) / length[:, None, None]
    out = out.reshape(p.shape[0], -1)
    return out[0] if single else out


def featurize(joints: np.ndarray, layout: str, dims: int, handedness: Any = "right") -> np.ndarray:
    """Dispatch to :func:`features_3d` (``dims == 3``) or :func:`features_2d` (``dims == 2``)."""
    if dims == 3:
        return features_3d(joints, layout, handedness)
    if dims == 2:
        return features_2d(joints, layout)
    raise ValueError(f"dims must be 2 or 3, got {dims}")
