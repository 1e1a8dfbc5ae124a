"""Comparisons of a paper number with ours, checks of a paper claim, and every rule that judges them.

A paper number is compared with our seed-level 95% interval (`Comparison`); a claim "A beats
B" with the paired difference of A and B over the seeds they share (`Difference`), and gets
exactly one of three verdicts (`VERDICTS`). The rules, all here:

- A paper number against ours (`Comparison.status`): inside our interval widened by the number's rounding, or outside.
- "A beats B" (`Difference.verdict`): supported when the whole 95% interval of A − B is above 0,
  contradicted when it is wholly below 0, not shown otherwise (one that holds 0, or one seed).
- "A beats every one of B, C, ..." (`beats_every`, `all_hold`): supported only when every
  difference is supported *and every named B is present*; contradicted when any difference is
  contradicted (one loss refutes "beats every one", whatever is missing); otherwise not shown,
  and a claim with a named B missing reads "not shown (missing: B)", never "supported" on the
  ones present.
- "A is no worse than B" (`no_worse`): a non-inferiority rule with a margin declared in the plan
  (plan.json's `no_worse_margin`, in the game's score units; default `NO_WORSE_SHARE` of the game's
  maximum score; `no_worse_margin()` reads it): supported when the whole interval of A − B is above −margin,
  contradicted when it is wholly below −margin, not shown otherwise. An interval that holds 0
  but reaches below −margin is not shown.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np
import pandas as pd

from analysis import paper
from analysis.loaders import max_score
from analysis.paper import label_name, population_name
from analysis.report.formatting import digits, fmt_ci, md_table, paper_tolerance
from analysis.summaries import paired_difference


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
        return f"{'**differs**' if self.differs else 'close'} (one seed): ours {word} by {abs(d):.{self.digits}f}"

    def row(self) -> list[str]:
        """Cells: what, paper, ours (mean [CI] (n)), verdict."""
        return [self.what, f"{self.paper_value:g}", fmt_ci(self.mean, self.lo, self.hi, self.n, self.digits), self.verdict]


# The only verdicts a claim can get: "A beats B" is supported when the whole 95% interval of
# A's advantage over B is above 0, contradicted when it is below 0, and not shown otherwise
# (an interval containing 0, one seed without an interval, or data missing).
SUPPORTED, NOT_SHOWN, CONTRADICTED = "supported", "not shown", "contradicted"
VERDICTS: tuple[str, ...] = (SUPPORTED, NOT_SHOWN, CONTRADICTED)

# The "no worse" margin when a plan declares none: this share of the game's maximum score (bandit
# 0.01, blocks 0.2, Hanabi 0.05), so that a loss too small to matter on the game's scale is tolerated
# and nothing larger is.
NO_WORSE_SHARE = 0.01


def verdict_cell(verdict: str, missing: Sequence[str] = ()) -> str:
    """The verdict as a table prints it: `not shown (missing: BaselineModular, First-Order MAML)` when named results are missing."""
    return f"{verdict} (missing: {', '.join(missing)})" if missing else verdict


def no_worse_margin(plan: dict[str, Any]) -> float:
    """The margin of "no worse" claims for a game: plan.json's `no_worse_margin`, else `NO_WORSE_SHARE` of its maximum score (nan if unknown)."""
    value = plan.get("no_worse_margin")
    return float(value) if value is not None else NO_WORSE_SHARE * max_score(plan)


@dataclass
class ClaimCheck:
    """A paper claim checked on our data: one of `VERDICTS`, with the evidence (the differences and their intervals)."""

    claim: paper.Claim
    scope: str
    verdict: str
    evidence: str
    game: str | None = None
    missing: tuple[str, ...] = ()  # results the claim names that this data lacks (display names)

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"verdict {self.verdict!r} is not one of {VERDICTS}")

    @classmethod
    def of(
        cls, claim: paper.Claim, scope: str, judgement: "Judgement", game: str | None = None, prefix: str = ""
    ) -> "ClaimCheck":
        """The check of `claim` on `scope` from a `Judgement` (its evidence after `prefix`, e.g. "AUC ")."""
        return cls(claim, scope, judgement.verdict, prefix + judgement.evidence, game, judgement.missing)

    @property
    def cell(self) -> str:
        """The verdict as printed: with what is missing, if anything is."""
        return verdict_cell(self.verdict, self.missing)

    def row(self) -> list[str]:
        """Cells: scope, verdict, evidence."""
        return [self.scope, self.cell, self.evidence]


@dataclass(frozen=True)
class Difference:
    """The difference `a` - `b` of two named results, oriented so that above 0 supports the claim, with its 95% interval over `n` units (seeds, or pairs of people)."""

    a: str
    b: str
    mean: float
    lo: float
    hi: float
    n: int

    @property
    def verdict(self) -> str:
        """Whether the claim "A beats B" is supported, contradicted or not shown by the interval."""
        if not (np.isfinite(self.lo) and np.isfinite(self.hi)):
            return NOT_SHOWN
        return SUPPORTED if self.lo > 0 else CONTRADICTED if self.hi < 0 else NOT_SHOWN

    def text(self, places: int = 3) -> str:
        """`A − B +0.012 [+0.004, +0.020] (n=3)`, or with `(n=1, no interval)` / `no shared seeds`."""
        if self.n == 0 or not np.isfinite(self.mean):
            return f"{self.a} − {self.b}: no shared seeds"
        if not (np.isfinite(self.lo) and np.isfinite(self.hi)):
            return f"{self.a} − {self.b} {self.mean:+.{places}f} (n={self.n}, no interval)"
        return f"{self.a} − {self.b} {self.mean:+.{places}f} [{self.lo:+.{places}f}, {self.hi:+.{places}f}] (n={self.n})"


@dataclass(frozen=True)
class Judgement:
    """A verdict (one of `VERDICTS`) with its evidence, and the named results it lacked (display names; empty if none)."""

    verdict: str
    evidence: str
    missing: tuple[str, ...] = ()

    @property
    def cell(self) -> str:
        """The verdict as printed: `not shown (missing: ...)` where something named is missing."""
        return verdict_cell(self.verdict, self.missing)


def all_hold(verdicts: Iterable[str], missing: Sequence[str] = ()) -> str:
    """The verdict on "A beats every B" from the verdicts on each B present: contradicted if any is, supported only if
    all are and none of the named Bs is `missing`, not shown otherwise."""
    verdicts = list(verdicts)
    if CONTRADICTED in verdicts:
        return CONTRADICTED
    return SUPPORTED if verdicts and not missing and all(v == SUPPORTED for v in verdicts) else NOT_SHOWN


def no_worse(diff: Difference, margin: float) -> str:
    """The verdict on "A is no worse than B" from the interval of A − B and the declared `margin` (>= 0, the game's score units).

    Supported when the whole interval is above −`margin`, contradicted when wholly below it, not shown otherwise
    (an interval that reaches below −`margin`, one seed, or no margin known).
    """
    if not (np.isfinite(diff.lo) and np.isfinite(diff.hi) and np.isfinite(margin)):
        return NOT_SHOWN
    if margin < 0:
        raise ValueError(f"no_worse_margin must be >= 0, got {margin}")
    return SUPPORTED if diff.lo > -margin else CONTRADICTED if diff.hi < -margin else NOT_SHOWN


def advantage(df: pd.DataFrame, a: str, b: str, value: str, within: Sequence[str], lower_is_better: bool = False) -> Difference:
    """Method `a`'s paired advantage over method `b` on the (seed, *`within`) units they share (rows of one population, by `label`).

    For returns it is A - B; for distances (`lower_is_better`) B - A, and the difference is named so.
    """
    first, second = (b, a) if lower_is_better else (a, b)
    return Difference(label_name(first), label_name(second), *paired_difference(df, first, second, value, within))


def beats_every(
    df: pd.DataFrame,
    a: str,
    named: Sequence[str],
    value: str,
    within: Sequence[str],
    places: int = 3,
    lower_is_better: bool = False,
) -> Judgement:
    """The verdict on "`a` beats every one of `named`" (labels), each paired difference its evidence.

    The claim is over every label in `named`: one that `df` lacks (or `a` itself lacking) makes it
    "not shown (missing: ...)" unless a present difference contradicts it (`all_hold`).
    """
    present = set(df["label"])
    missing = tuple(label_name(x) for x in (a, *named) if x not in present)
    diffs = [advantage(df, a, b, value, within, lower_is_better) for b in named if b in present] if a in present else []
    evidence = "; ".join(d.text(places) for d in diffs) or "nothing to compare"
    return Judgement(all_hold((d.verdict for d in diffs), missing), evidence, missing)


def beats_all(
    df: pd.DataFrame,
    a: str,
    others: Sequence[str],
    value: str,
    within: Sequence[str],
    places: int = 3,
    lower_is_better: bool = False,
) -> tuple[str, str]:
    """The verdict on "`a` beats every one of `others`" and its evidence (each paired difference with its interval).

    As `beats_every`, the verdict one of `VERDICTS`; anything missing is named at the head of the evidence.
    """
    found = beats_every(df, a, others, value, within, places, lower_is_better)
    return found.verdict, (f"missing: {', '.join(found.missing)}; " if found.missing else "") + found.evidence


def variants_block(
    frame: pd.DataFrame,
    value: str,
    within: Sequence[str],
    claimed: Iterable[str],
    against: Sequence[str],
    question: str,
    lower_is_better: bool = False,
    places: int | None = None,
) -> list[str]:
    """Markdown lines: each method of `frame` that the paper's claims are not about (not in `claimed`: other λ, low-dim z,
    the head penalty, head pick, ...) judged against the baselines `against` by the paired rule; empty if there is none.

    Differences are printed with `places` decimals (default: the game's); a baseline of `against` missing from a
    population makes its rows "not shown (missing: ...)" (`beats_every`). These rows never enter a verdict on the
    paper: the paper's claims are checked on its own method alone.
    """
    claimed = set(claimed)
    rows = []
    for population in sorted(frame["population"].unique()):
        p = frame[frame["population"] == population]
        if not any(lab in set(p["label"]) for lab in against):
            continue
        for label in sorted(set(p["label"]) - claimed):
            decimals = places if places is not None else digits(p["game"].iloc[0])
            found = beats_every(p, label, against, value, within, decimals, lower_is_better)
            rows.append([population_name(population), label_name(label), found.cell, found.evidence])
    if not rows:
        return []
    return [
        "",
        "### Variants of ours and other agents not checked against the paper (other λ, low-dim z, head penalty, head pick, PPO_BC, ...)",
        "",
        "Judged by the same paired rule as the paper's claims; they never change a verdict on the paper, which is checked on ours λ=0.5 alone.",
        "",
        md_table(["population", "method", question, "evidence (paired differences over seeds)"], rows),
        "",
    ]


def claims_block(topic: str, claims: Iterable[Any], checks: list[ClaimCheck], rule: str) -> list[str]:
    """Markdown lines: each of the paper's `claims` on `topic` with the table of its `checks` (none if unchecked), after the `rule` that judged them."""
    if not checks:
        return []
    lines = ["", f"### The paper's claims on {topic}, checked", "", rule, ""]
    for claim in claims:
        mine = [c for c in checks if c.claim.key == claim.key]
        if mine:
            lines += [
                f"*{claim.text}* ({claim.source})",
                "",
                md_table(["scope", "verdict", "evidence"], [c.row() for c in mine]),
                "",
            ]
    return lines
