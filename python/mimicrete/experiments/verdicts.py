"""Where each group agrees with the paper's Table 5 and where it does not: the generated sentences
of the report's comparison section (the rule itself, ``agrees``, is in ``stats``)."""

from __future__ import annotations

import math

from .markdown import steps as _steps
from .paper import PAPER_MAX_STEPS, PAPER_TABLE5
from .stats import GroupStats, agrees


def _sampled_verdict(st: GroupStats, paper: tuple[float, float, float]) -> str:
    """ " Sampled: ... (agrees / differs on ...)." for a group with sampled evaluations."""
    if st.installed_sampled[2] == 0:
        return ""
    pp, pi, pl = paper
    off = [
        label
        for label, ours, ref, rate in (
            ("picked", st.picked_sampled, pp, True),
            ("installed", st.installed_sampled, pi, True),
            ("episode length", st.length_sampled, pl, False),
        )
        if agrees(ours, ref, rate=rate) is False
    ]
    vals = (
        f"picked {100 * st.picked_sampled[0]:.0f} %, installed "
        f"{100 * st.installed_sampled[0]:.0f} %, episode length {st.length_sampled[0]:.0f}"
    )
    verdict = "agrees with the paper" if not off else f"differs on {', '.join(off)}"
    return f" Sampled policy: {vals}, which {verdict}."


def comparison_lines(stats: dict[int, GroupStats], budget: int | None) -> list[str]:
    """Generated sentences: where each group agrees with Table 5 and where it does not."""
    lines = []
    for g, st in sorted(stats.items()):
        if g not in PAPER_TABLE5 or st.installed[2] == 0:
            continue
        pp, pi, pl = PAPER_TABLE5[g]
        parts, diffs = [], []
        for label, ours, paper, rate in (
            ("picked", st.picked, pp, True),
            ("installed", st.installed, pi, True),
            ("episode length", st.length, pl, False),
        ):
            ok = agrees(ours, paper, rate=rate)
            if ok is None:
                continue
            if rate:
                txt = f"{label} {100 * ours[0]:.0f} % vs the paper's {100 * paper:.0f} %"
            else:
                txt = f"{label} {ours[0]:.0f} vs {paper:.0f}"
            (parts if ok else diffs).append(txt)
        sampled = _sampled_verdict(st, (pp, pi, pl))
        if not diffs:
            lines.append(f"- Group {g} **agrees** with the paper ({'; '.join(parts)}).{sampled}")
            continue
        s = f"- Group {g} **differs** from the paper: {'; '.join(diffs)}"
        if parts:
            s += f" (agrees on {'; '.join(parts)})"
        s += "." + sampled
        hints = []
        budget = st.budget or budget
        if budget and budget < PAPER_MAX_STEPS and st.installed[0] < pi:
            hints.append(
                f"our budget was {_steps(budget)} steps, {100 * budget / PAPER_MAX_STEPS:.0f} % "
                "of the paper's 5M"
            )
            if math.isfinite(st.trend) and st.trend > 0.05:
                hints.append(
                    "its training installed rate was still rising at the cut "
                    f"(+{100 * st.trend:.0f} points over the last 10 % of steps)"
                )
        if hints:
            s += " Data: " + "; ".join(hints) + "."
        lines.append(s)
    return lines
