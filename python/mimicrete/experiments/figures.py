"""The report's figures: Fig. 7's three panels (cumulative reward and installed rate, mean over
seeds with a 95 % band) and the GAIL loss of groups 2-4 (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .paper import FIG7_PANELS, PAPER_GAIL_LOSS
from .stats import (
    TAG_GAIL_LOSS,
    TAG_INSTALLED,
    TAG_PICKED,
    TAG_REWARD,
    curve_band,
    held_to_budget,
)
from .sweep_runs import Run


def _plot_panel(
    ax, runs_by_group: dict[int, list[Run]], groups: list[int], tag: str, hold: bool = False
) -> bool:
    """One panel: every group's seed mean and band; ``hold``: a run that stopped on convergence
    counts at its last value up to where the group's curves end."""
    drew = False
    for g in groups:
        runs = [r for r in runs_by_group.get(g, []) if tag in r.scalars and len(r.scalars[tag][0])]
        # held to where the group's longest curve ends (a last rollout can pass the budget)
        end = max(
            [r.scalars[tag][0][-1] for r in runs] + [r.max_steps or 0 for r in runs], default=0
        )
        curves = [
            held_to_budget(*r.scalars[tag], r.converged_at, end) if hold else r.scalars[tag]
            for r in runs
        ]
        if not curves:
            continue
        grid, mean, lo, hi = curve_band(curves)
        if tag in (TAG_INSTALLED, TAG_PICKED):  # a rate's band stays inside [0, 1]
            lo, hi = np.clip(lo, 0.0, 1.0), np.clip(hi, 0.0, 1.0)
        (line,) = ax.plot(grid, mean, lw=1.5, label=f"Group {g} (n={len(curves)})")
        ax.fill_between(grid, lo, hi, color=line.get_color(), alpha=0.2, lw=0)
        drew = True
    return drew


def write_figures(runs: list[Run], fig_dir: Path) -> dict[str, Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig_dir.mkdir(parents=True, exist_ok=True)
    by_group: dict[int, list[Run]] = {}
    for r in runs:
        if r.status != "error" and r.scalars:
            by_group.setdefault(r.group, []).append(r)
    out: dict[str, Path] = {}
    for key, (title, groups) in FIG7_PANELS.items():
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        drew = False
        for ax, (tag, ylabel) in zip(
            axes,
            ((TAG_REWARD, "cumulative reward"), (TAG_INSTALLED, "installed rate (training)")),
            strict=True,
        ):
            drew |= _plot_panel(ax, by_group, groups, tag, hold=True)
            ax.set_xlabel("env steps")
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=8)
        fig.suptitle(f"Fig. 7{key}: {title} (mean over seeds, 95 % CI)")
        fig.tight_layout()
        if drew:
            p = fig_dir / f"fig7{key}_{title.replace(' ', '_')}.png"
            fig.savefig(p, dpi=100)
            out[key] = p
        plt.close(fig)
    fig, ax = plt.subplots(figsize=(6.5, 4))
    if _plot_panel(ax, by_group, sorted(PAPER_GAIL_LOSS), TAG_GAIL_LOSS):
        ax.set_xlabel("env steps")
        ax.set_ylabel("GAIL loss")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        ax.set_title("GAIL loss, groups 2–4 (mean over seeds, 95 % CI)")
        fig.tight_layout()
        p = fig_dir / "gail_loss.png"
        fig.savefig(p, dpi=100)
        out["gail"] = p
    plt.close(fig)
    return out
