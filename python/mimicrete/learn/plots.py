"""Learning-curve PNGs from a run's ``scalars.csv``, and success maps over the table from an
evaluation's episodes (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .evaluate import percent  # noqa: E402
from .run_files import read_scalars  # noqa: E402

CURVES = [
    ("Environment/Cumulative Reward", "extrinsic reward per episode", "extrinsic_reward.png"),
    ("Environment/Picked Rate", "picked rate", "picked_rate.png"),
    ("Environment/Installed Rate", "installed rate", "installed_rate.png"),
]


def learning_curves(run_dir: Path, out_dir: Path | None = None) -> list[Path]:
    """One PNG per curve plus ``learning_curves.png`` with all three; returns the paths."""
    run_dir = Path(run_dir)
    out_dir = Path(out_dir or run_dir / "plots")
    out_dir.mkdir(parents=True, exist_ok=True)
    data = read_scalars(run_dir)
    paths = []
    fig_all, axes = plt.subplots(1, len(CURVES), figsize=(5 * len(CURVES), 3.6))
    for ax_all, (tag, label, fname) in zip(axes, CURVES, strict=True):
        xs, ys = data.get(tag, ([], []))
        fig, ax = plt.subplots(figsize=(6, 4))
        for a in (ax, ax_all):
            a.plot(xs, ys, lw=1.5)
            a.set_xlabel("env steps")
            a.set_ylabel(label)
            a.set_title(f"{run_dir.name}: {label}")
            a.grid(alpha=0.3)
        fig.tight_layout()
        _save(fig, out_dir / fname)
        plt.close(fig)
        paths.append(out_dir / fname)
    fig_all.tight_layout()
    _save(fig_all, out_dir / "learning_curves.png")
    plt.close(fig_all)
    paths.append(out_dir / "learning_curves.png")
    return paths


def compare(run_dirs: list[Path], out: Path, tag: str = "Environment/Installed Rate") -> Path:
    """Overlay one scalar of several runs (e.g. the nine groups) in one PNG."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for rd in run_dirs:
        xs, ys = read_scalars(Path(rd)).get(tag, ([], []))
        ax.plot(xs, ys, lw=1.3, label=Path(rd).name)
    ax.set_xlabel("env steps")
    ax.set_ylabel(tag)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, Path(out))
    plt.close(fig)
    return out


def success_map(
    panels: list[tuple[str, list[dict[str, Any]]]],
    out: Path,
    bins: tuple[int, int] = (5, 4),
    marked: list[list[float]] | None = None,
    word: str = "installed",
) -> Path:
    """Success rate as a heat map over the object's start x, y, one panel per ``(title,
    episodes)`` (an evaluation's ``per_episode`` records: ``object_pose`` and ``installed``), all
    on the same ``bins`` (x, y) cells spanning the starts given; each cell reads its rate and
    its number of episodes. ``marked``: object poses drawn as dots (the training starts);
    ``word``: what a success is called (``installed``, or ``placed`` for a task judged by the
    placed rule: :func:`mimicrete.learn.evaluate.success_word`)."""
    xy = np.array([e["object_pose"][:2] for _, eps in panels for e in eps], float)
    if xy.size == 0:
        raise ValueError("success_map: no episode with an object_pose")
    lo, hi = xy.min(0), xy.max(0)
    pad = np.maximum(0.02 * (hi - lo), 1e-3)  # the extreme starts fall inside the outer cells
    xe = np.linspace(lo[0] - pad[0], hi[0] + pad[0], bins[0] + 1)
    ye = np.linspace(lo[1] - pad[1], hi[1] + pad[1], bins[1] + 1)
    fig, axes = plt.subplots(
        1, len(panels), figsize=(5.4 * len(panels), 2.9), squeeze=False, layout="constrained"
    )
    for ax, (title, eps) in zip(axes[0], panels, strict=True):
        p = np.array([e["object_pose"][:2] for e in eps], float).reshape(-1, 2)
        ok = np.array([bool(e["installed"]) for e in eps], float)
        n, _, _ = np.histogram2d(p[:, 0], p[:, 1], bins=(xe, ye))
        k, _, _ = np.histogram2d(p[:, 0], p[:, 1], bins=(xe, ye), weights=ok)
        rate = np.where(n > 0, k / np.maximum(n, 1), np.nan)
        im = ax.pcolormesh(xe, ye, rate.T, cmap="RdYlGn", vmin=0, vmax=1)
        for i in range(bins[0]):
            for j in range(bins[1]):
                if n[i, j]:
                    ax.text((xe[i] + xe[i + 1]) / 2, (ye[j] + ye[j + 1]) / 2,
                            f"{rate[i, j]:.0%}\n{int(n[i, j])}", ha="center", va="center",
                            fontsize=7)  # fmt: skip
        if marked:
            m = np.array([q[:2] for q in marked], float)
            ax.plot(m[:, 0], m[:, 1], "k.", ms=3)
        ax.set_title(f"{title}: {percent(ok.mean())} of {len(eps)} {word}", fontsize=9)
        ax.set_xlabel("tile start x (m, Base)" + ("; dots: the training starts" if marked else ""))
        ax.set_ylabel("tile start y (m)")
        ax.set_aspect("equal")
    fig.colorbar(im, ax=axes[0].tolist(), label=f"{word} rate", shrink=0.8)
    _save(fig, Path(out))
    plt.close(fig)
    return Path(out)


def _save(fig: Any, path: Path) -> None:
    """A PNG written whole or not at all."""
    from mimicrete.safe_io import atomic_output

    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", bbox_inches="tight")
