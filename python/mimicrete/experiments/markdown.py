"""Markdown for the reports (``report.py``, ``demos_needed.py``): numbers as the tables print
them and the tables themselves."""

from __future__ import annotations

import math


def pct(ms: tuple[float, float, int]) -> str:
    """A rate's (mean, sd, n) over seeds: "95 ± 5 %", "95 %" for one seed, "–" for none."""
    m, sd, n = ms
    if n == 0:
        return "–"
    return f"{100 * m:.0f} ± {100 * sd:.0f} %" if n > 1 else f"{100 * m:.0f} %"


def num(ms: tuple[float, float, int], fmt: str = ".0f") -> str:
    """A number's (mean, sd, n) over seeds, like :func:`pct`."""
    m, sd, n = ms
    if n == 0:
        return "–"
    return f"{m:{fmt}} ± {sd:{fmt}}" if n > 1 else f"{m:{fmt}}"


def steps(x: float | int | None) -> str:
    """A step count: "1.50M", "300k", "512"; "–" for none."""
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    x = float(x)
    if x >= 1e6:
        return f"{x / 1e6:.2f}M"
    if x >= 1e3:
        return f"{x / 1e3:.0f}k"
    return f"{x:.0f}"


def listing(items) -> str:
    """Sorted items joined by commas: "2, 3, 9"."""
    return ", ".join(str(g) for g in sorted(items))


def table(columns: list[str], rows: list[list[object]]) -> list[str]:
    """A Markdown table: the header of ``columns``, its rule and one line a row."""
    return [
        "| " + " | ".join(columns) + " |",
        "|" + "---|" * len(columns),
        *("| " + " | ".join(map(str, row)) + " |" for row in rows),
    ]
