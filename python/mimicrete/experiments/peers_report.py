"""The peers' results as a table and a figure (``python -m mimicrete.experiments.peers report``),
made from the JSON files ``peers run`` wrote and nothing else; see ``peers.py`` for how they are
made.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from mimicrete._native import MimicreteError

LABELS = {
    "act": "ACT (LeRobot)",
    "diffusion": "Diffusion Policy (LeRobot)",
    "ours": "ours (demogen + wide_gen)",
    "paper": "paper's recipe (group 4)",
}
STARTS = ("training", "robust", "wide")
TABLE_BEGIN = "<!-- peers:table -->"
TABLE_END = "<!-- /peers:table -->"
FIGURE = "peers_vs_demos.png"
#: line styles of the figure: a hollow large marker under a small filled one, so that two methods
#: at the same value both show
STYLE: dict[str, dict[str, Any]] = {
    "act": {"marker": "o", "markersize": 10, "markerfacecolor": "none", "lw": 2.5},
    "diffusion": {"marker": "s", "markersize": 4, "ls": "--", "lw": 1.2},
    "ours": {"marker": "D", "markersize": 6, "lw": 2.0, "color": "tab:green"},
    "paper": {"marker": "^", "markersize": 6, "ls": ":", "lw": 1.5, "color": "tab:red"},
}


class PeersError(MimicreteError, RuntimeError):
    """A step of the pipeline failed (one line, with the log file to read)."""


RESULT_FIELDS = (
    "method",
    "demos",
    "starts",
    "episodes",
    "installed_rate",
    "picked_rate",
    "mean_episode_length",
    "steps",
    "epochs",
    "batch_size",
    "train_wall_s",
    "train_cpu_s",
    "eval_wall_s",
)


def load_results(out: Path) -> list[dict[str, Any]]:
    d = out / "results"
    if not d.is_dir():
        raise PeersError(f"{d}: no such directory (`python -m mimicrete.experiments.peers run`)")
    rows = []
    for f in sorted(d.glob("*.json")):
        r = json.loads(f.read_text())
        missing = [k for k in RESULT_FIELDS if k not in r]
        if missing:
            raise PeersError(f"{f}: missing {', '.join(missing)}")
        rows.append(r)
    if not rows:
        raise PeersError(f"{d}: no results")
    return rows


def _pct(x: float) -> str:
    return f"{100 * x:.0f} %"


def _budget(r: dict[str, Any]) -> str:
    """Steps x batch (epochs) of an offline learner; env steps of one trained on the env (with
    its cap when it stopped on convergence)."""
    if r["batch_size"] is None:
        cap = r.get("budget_asked")
        if r.get("stop_on_convergence") and cap:
            return f"{r['steps']:,} env steps (converged; cap {cap:,})"
        return f"{r['steps']:,} env steps"
    return f"{r['steps']} × {r['batch_size']} ({r['epochs']:g})"


def _train_clock(r: dict[str, Any]) -> str:
    text = f"{r['train_wall_s'] / 60:.1f} min ({r['train_cpu_s'] / 60:.1f} min)"
    if r.get("gen_wall_s"):
        text += f" + demogen {r['gen_wall_s']:.0f} s"
    return text


def table(rows: list[dict[str, Any]]) -> str:
    """One row per (method, demo count): success per start set, budget and wall clock."""
    starts = [s for s in STARTS if any(r["starts"] == s for r in rows)]
    order = {m: i for i, m in enumerate(LABELS)}
    keys = sorted({(r["method"], r["demos"]) for r in rows}, key=lambda k: (order.get(k[0], 9), k))
    by = {(r["method"], r["demos"], r["starts"]): r for r in rows}
    head = ["method", "demos"]
    for s in starts:
        head += [f"installed ({s})", f"picked ({s})", f"length ({s})"]
    head += [
        "steps × batch (epochs)",
        "training wall clock (CPU)",
        f"evaluation wall clock ({' / '.join(starts)})",
    ]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for m, n in keys:
        any_r = next(by[(m, n, s)] for s in starts if (m, n, s) in by)
        cells = [LABELS.get(m, m), str(n)]
        for s in starts:
            r = by.get((m, n, s))
            if r is None:
                cells += ["–", "–", "–"]
            else:
                cells += [
                    _pct(r["installed_rate"]),
                    _pct(r["picked_rate"]),
                    f"{r['mean_episode_length']:.0f}",
                ]
        evals = " / ".join(
            f"{by[(m, n, s)]['eval_wall_s']:.0f} s" if (m, n, s) in by else "–" for s in starts
        )
        cells += [_budget(any_r), _train_clock(any_r), evals]
        lines.append("| " + " | ".join(cells) + " |")
    eps = sorted({r["episodes"] for r in rows})
    lines.append("")
    lines.append(
        f"Installed / picked: share of {'/'.join(map(str, eps))} deterministic episodes; length: "
        "mean steps per episode (750 = cut at the limit)."
    )
    return "\n".join(lines) + "\n"


def figure(rows: list[dict[str, Any]], path: Path) -> Path:
    """Installed rate against demo count, one line per method, one panel per start set."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    starts = [s for s in STARTS if any(r["starts"] == s for r in rows)]
    fig, axes = plt.subplots(1, len(starts), figsize=(4.2 * len(starts), 3.4), squeeze=False)
    counts = sorted({r["demos"] for r in rows})
    for ax, s in zip(axes[0], starts, strict=True):
        for m in sorted({r["method"] for r in rows}):
            pts = sorted(
                (r["demos"], r["installed_rate"])
                for r in rows
                if (r["method"], r["starts"]) == (m, s)
            )
            if pts:
                xs, ys = zip(*pts, strict=True)
                ax.plot(xs, [100 * y for y in ys], label=LABELS.get(m, m), **STYLE.get(m, {}))
        ax.set_xscale("log")
        ax.set_xticks(counts, [str(c) for c in counts])
        ax.minorticks_off()
        ax.set_ylim(-3, 103)
        ax.set_xlabel("demos")
        ax.set_ylabel("installed (%)")
        ax.set_title(f"{s} starts", fontsize=10)
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def replace_table(doc: Path, text: str) -> None:
    """Put ``text`` between :data:`TABLE_BEGIN` and :data:`TABLE_END` in ``doc``."""
    old = doc.read_text()
    if TABLE_BEGIN not in old or TABLE_END not in old:
        raise PeersError(f"{doc}: no {TABLE_BEGIN} ... {TABLE_END} markers for the table")
    head, rest = old.split(TABLE_BEGIN, 1)
    _, tail = rest.split(TABLE_END, 1)
    doc.write_text(head + TABLE_BEGIN + "\n" + text + TABLE_END + tail)


def report(out: Path, md: Path | None, fig: Path, into: Path | None) -> tuple[Path, Path]:
    rows = load_results(out)
    text = table(rows)
    md = md or out / "summary.md"
    md.parent.mkdir(parents=True, exist_ok=True)
    md.write_text(text)
    figure(rows, fig)
    if into is not None:
        replace_table(into, text)
    return md, fig


# ------------------------------------------------------------------------------------- the CLI
