"""A camera's view of an ArUco marker on the tile, drawn by projecting the marker's image through
a pinhole camera (the deploy tests' stand-in for a real camera)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

K = np.array([[600.0, 0.0, 320.0], [0.0, 600.0, 240.0], [0.0, 0.0, 1.0]])
SIZE = (640, 480)
MARKER_ID = 7
MARKER_SIZE = 0.05  # the black square's side, m
TILE_TOP = 0.01  # the tile's top face above the table, m


def base_from_camera() -> np.ndarray:
    """A camera 0.7 m above the table over the tiles' area, looking straight down."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # x along Base x, z down
    T[:3, 3] = [0.12, 0.30, 0.70]
    return T


def write_calibration(path: Path, **override) -> Path:
    d = {
        "camera_matrix": K.tolist(),
        "dist_coeffs": [0.0] * 5,
        "base_from_camera": base_from_camera().tolist(),
        "marker": {"dictionary": "DICT_4X4_50", "id": MARKER_ID, "size": MARKER_SIZE},
    }
    d.update(override)
    path.write_text(json.dumps(d))
    return path


def render(x: float, y: float, yaw: float, tilt_deg: float = 0.0) -> np.ndarray:
    """The camera's grey image of the marker centred on a tile at (x, y, yaw) (tilted about its
    x axis by ``tilt_deg``)."""
    import cv2

    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    px, pad = 200, 40
    patch = np.full((px + 2 * pad, px + 2 * pad), 255, np.uint8)
    patch[pad : pad + px, pad : pad + px] = cv2.aruco.generateImageMarker(d, MARKER_ID, px)
    # the patch's corners (white margin included) in the tile's frame: x right, y up
    scale = MARKER_SIZE / px
    c, s = math.cos(yaw), math.sin(yaw)
    t = math.radians(tilt_deg)
    out = []
    for u, v in [(0, 0), (px + 2 * pad, 0), (px + 2 * pad, px + 2 * pad), (0, px + 2 * pad)]:
        lx, ly = (u - pad - px / 2) * scale, -(v - pad - px / 2) * scale
        ly, lz = ly * math.cos(t), ly * math.sin(t)
        p = np.array([x + c * lx - s * ly, y + s * lx + c * ly, TILE_TOP + lz, 1.0])
        pc = np.linalg.inv(base_from_camera()) @ p
        uv = K @ (pc[:3] / pc[2])
        out.append(uv[:2])
    whole = np.array([[0, 0], [px + 2 * pad, 0], [px + 2 * pad, px + 2 * pad], [0, px + 2 * pad]],
                     np.float32)  # fmt: skip
    H = cv2.getPerspectiveTransform(whole, np.asarray(out, np.float32))
    return cv2.warpPerspective(patch, H, SIZE, borderValue=128)


def write_video(path: Path, poses: list[tuple[float, float, float]], fps: float = 25.0) -> Path:
    import cv2

    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, SIZE, isColor=False)
    assert w.isOpened(), "no MJPG writer"
    for p in poses:
        w.write(render(*p))
    w.release()
    return path
