"""Learning-curve PNGs from a run's ``scalars.csv`` (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

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


def _save(fig: Any, path: Path) -> None:
    """A PNG written whole or not at all."""
    from mimicrete.safe_io import atomic_output

    with atomic_output(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
