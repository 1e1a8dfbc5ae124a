"""Formatting shared by the report's sections: numbers with intervals, markdown tables, the paper's rounding."""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

import numpy as np


def digits(game: str | None) -> int:
    return 2 if game in ("blocks",) else 3


def fmt_ci(mean: float, lo: float, hi: float, n: int, digits: int = 3) -> str:
    """`mean [lo, hi] (n=..)`, or `mean (n=1, no interval)`, or `—` when there is no data."""
    if n == 0 or not np.isfinite(mean):
        return "—"
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"{mean:.{digits}f} (n={n}, no interval)"
    return f"{mean:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}] (n={n})"


def fmt_summary(row: Mapping[str, Any], digits: int = 3) -> str:
    """`fmt_ci` of one row of a `summarise` / `seed_summary` frame (mean, lo, hi, n)."""
    return fmt_ci(float(row["mean"]), float(row["lo"]), float(row["hi"]), int(row["n"]), digits)


def md_table(headers: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """A GitHub-markdown table (cells converted with str, pipes escaped)."""

    def cell(x: object) -> str:
        return str(x).replace("|", "\\|").replace("\n", " ")

    lines = ["| " + " | ".join(map(cell, headers)) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(map(cell, r)) + " |" for r in rows]
    return "\n".join(lines)


def paper_tolerance(value: float) -> float:
    """Half a unit of the last digit the paper printed (0.005 for 0.89, 0.00005 for 0.9545)."""
    text = f"{value:.6f}".rstrip("0").rstrip(".")
    decimals = len(text.split(".")[1]) if "." in text else 0
    return 0.5 * 10 ** (-max(decimals, 2))
