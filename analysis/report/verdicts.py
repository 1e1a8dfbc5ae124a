"""Comparisons of a paper number with ours, checks of a paper claim, and the rules that judge them."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np
import pandas as pd

from analysis import paper
from analysis.report.formatting import fmt_ci, md_table, paper_tolerance


@dataclass
class Comparison:
    """One paper number beside ours: the verdict and the data-derived reasons when they differ."""

    section: str
    what: str
    paper_value: float
    paper_source: str
    mean: float
    lo: float
    hi: float
    n: int
    digits: int = 3
    reasons: list[str] = field(default_factory=list)
    higher_is_better: bool = True  # returns; False for distances

    @property
    def direction(self) -> str:
        """Whether ours is better or worse than the paper's number (by the mean)."""
        better = self.mean > self.paper_value if self.higher_is_better else self.mean < self.paper_value
        return "ours is better" if better else "ours is worse"

    @property
    def status(self) -> str:
        """'not run', 'no interval', 'inside' or 'outside'."""
        if self.n == 0 or not np.isfinite(self.mean):
            return "not run"
        if not (np.isfinite(self.lo) and np.isfinite(self.hi)):
            return "no interval"
        tol = paper_tolerance(self.paper_value)
        return "inside" if self.lo - tol <= self.paper_value <= self.hi + tol else "outside"

    @property
    def differs(self) -> bool:
        """True when the paper's number is outside our interval, or (no interval) further than 10% of the scale from ours."""
        if self.status == "outside":
            return True
        if self.status == "no interval":
            return abs(self.mean - self.paper_value) > 0.1 * max(1.0, abs(self.paper_value))
        return False

    @property
    def verdict(self) -> str:
        """The table's verdict text: inside our interval, or by how much ours is higher or lower."""
        d = self.mean - self.paper_value
        word = "higher" if d > 0 else "lower"
        if self.status == "not run":
            return "not run"
        if self.status == "inside":
            return "paper inside our 95% CI"
        if self.status == "outside":
            return f"**differs**: ours {word} by {abs(d):.{self.digits}f}"
        return f"{'**differs**' if self.differs else 'close'} (single run): ours {word} by {abs(d):.{self.digits}f}"

    def row(self) -> list[str]:
        """Cells: what, paper, ours (mean [CI] (n)), verdict."""
        return [self.what, f"{self.paper_value:g}", fmt_ci(self.mean, self.lo, self.hi, self.n, self.digits), self.verdict]


@dataclass
class ClaimCheck:
    """A paper claim checked on our data: 'supported', 'supported (intervals overlap)', 'not shown (intervals overlap)',
    'contradicted', 'undetermined'."""

    claim: paper.Claim
    scope: str
    verdict: str
    evidence: str
    game: str | None = None

    def row(self) -> list[str]:
        """Cells: scope, verdict, evidence."""
        return [self.scope, self.verdict, self.evidence]


def compare(a: tuple[float, float, float], b: tuple[float, float, float]) -> str:
    """'clear' if a's interval is above b's, 'mean' if only a's mean is higher, 'tie' if a's mean is not higher
    but the intervals overlap, 'no' otherwise (a's interval below b's, or no intervals to tell)."""
    if a[0] > b[0]:
        return "clear" if np.isfinite(a[1]) and np.isfinite(b[2]) and a[1] > b[2] else "mean"
    return "tie" if np.isfinite(a[2]) and np.isfinite(b[1]) and a[2] >= b[1] else "no"


def overall_verdict(outcomes: list[str]) -> str:
    """The verdict on 'a beats every b' from `compare`'s outcomes: a lower mean inside overlapping
    intervals is 'not shown', not 'contradicted'."""
    if all(o == "clear" for o in outcomes):
        return "supported"
    if all(o in ("clear", "mean") for o in outcomes):
        return "supported (intervals overlap)"
    return "contradicted" if "no" in outcomes else "not shown (intervals overlap)"


def against(p: pd.DataFrame, label: str, others: list[str]) -> dict[str, str]:
    """`compare`'s outcome of `label` against each of `others` (rows of one population's AUC summary, by label)."""
    a = (p.at[label, "mean"], p.at[label, "lo"], p.at[label, "hi"])
    return {lab: compare(a, (p.at[lab, "mean"], p.at[lab, "lo"], p.at[lab, "hi"])) for lab in others}


def claims_block(topic: str, claims: Iterable[Any], checks: list[ClaimCheck]) -> list[str]:
    """Markdown lines: each of the paper's `claims` on `topic` with the table of its `checks` (none if unchecked)."""
    if not checks:
        return []
    lines = ["", f"### The paper's claims on {topic}, checked", ""]
    for claim in claims:
        mine = [c for c in checks if c.claim.key == claim.key]
        if mine:
            lines += [f"*{claim.text}* ({claim.source})", "", md_table(["scope", "verdict", "evidence"], [c.row() for c in mine]), ""]
    return lines
