"""The ``rgb_array`` rendering of the gymnasium envs (:mod:`mimicrete.envs`): a top (x-y) and a
side (x-z) orthographic drawing of a simulator scene (``SimEnv.scene()``) at a snapshot
(``SimEnv.snapshot()``), with matplotlib's Agg canvas."""

from __future__ import annotations

from typing import Any

import numpy as np

from mimicrete.kin import quat_matrix


def _frame(item: dict[str, Any], snap: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    fr = item["frame"]
    if fr == "world":
        return np.eye(3), np.zeros(3)
    if fr == "object":
        p = snap["object"]
    elif fr.startswith("object"):  # "object<i>": tile i of a row (the snapshot's row[i])
        p = snap["row"][int(fr[6:])]["object"]
    else:
        p = snap["links"][int(fr[4:])]
    return quat_matrix(p["q"]), np.asarray(p["t"], dtype=float)


def _cross2(u: np.ndarray, v: np.ndarray) -> float:
    return float(u[0] * v[1] - u[1] * v[0])


def _hull(pts: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain) of 2-D points."""
    pts = np.unique(np.round(pts, 9), axis=0)
    if len(pts) <= 2:
        return pts
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]

    def half(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and _cross2(out[-1] - out[-2], p - out[-2]) <= 0:
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def render_rgb(
    scene: list[dict[str, Any]], snap: dict[str, Any], size: tuple[int, int] = (640, 320)
) -> np.ndarray:
    """Top (x-y) and side (x-z) orthographic drawing of the scene → ``(H, W, 3)`` uint8."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon

    fig = Figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    axes = fig.subplots(1, 2)
    views = [(0, 1, "top (x, y)"), (0, 2, "side (x, z)")]
    for ax, (_, j, title) in zip(axes, views, strict=True):
        ax.set_title(title, fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlim(-0.55, 0.45)
        ax.set_ylim(-0.15, 0.6) if j == 1 else ax.set_ylim(-0.1, 0.55)
        ax.tick_params(labelsize=6)
    for item in scene:
        if item["name"] == "table":
            continue
        rot, org = _frame(item, snap)
        local_r = quat_matrix(item["rotation"])
        local_t = np.asarray(item["translation"], dtype=float)
        color = tuple(item["rgba"][:3])
        alpha = float(item["rgba"][3])
        kind = item["kind"]
        if kind == "capsule":
            a = rot @ (local_r @ np.asarray(item["a"]) + local_t) + org
            b = rot @ (local_r @ np.asarray(item["b"]) + local_t) + org
            width = float(item["radius"]) * 2 * 100 * 1.0
            for ax, (i, j, _) in zip(axes, views, strict=True):
                ax.plot(
                    [a[i], b[i]],
                    [a[j], b[j]],
                    color=color,
                    lw=max(width, 1.0),
                    solid_capstyle="round",
                    alpha=alpha,
                )
            continue
        if kind == "box":
            h = np.asarray(item["half_extents"], dtype=float)
        else:
            r, hh = float(item["radius"]), float(item["half_height"])
            h = np.array([r, r, hh])
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
        world = (rot @ (local_r @ corners.T + local_t[:, None])).T + org
        for ax, (i, j, _) in zip(axes, views, strict=True):
            hull = _hull(world[:, [i, j]])
            if len(hull) >= 3:
                ax.add_patch(
                    Polygon(hull, closed=True, facecolor=color, edgecolor="k", lw=0.3, alpha=alpha)
                )
    axes[1].axhline(0.0, color=(0.45, 0.35, 0.25), lw=2)
    label = f"step {snap['step']}  held={snap['held']}  picked={snap['picked']}"
    fig.suptitle(label, fontsize=8)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    return img
