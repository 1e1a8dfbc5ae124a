"""Section: where ours differs from the paper, and why (the summary built from every other section)."""

from __future__ import annotations

from analysis.report.context import Context
from analysis.report.formatting import fmt_ci
from analysis.report.verdicts import CONTRADICTED, NOT_SHOWN, SUPPORTED


def differences_section(ctx: Context) -> str:
    lines = ["## Where ours differs from the paper, and why", ""]
    inside = [c for c in ctx.comparisons if c.status == "inside"]
    differ = [c for c in ctx.comparisons if c.differs]
    close = [c for c in ctx.comparisons if c.status == "no interval" and not c.differs]
    count = {v: sum(c.verdict == v for c in ctx.claims) for v in (SUPPORTED, NOT_SHOWN, CONTRADICTED)}
    lines.append(
        f"{len(ctx.comparisons)} paper numbers compared: {len(inside)} inside our seed-level 95% interval, {len(differ)} differ, "
        f"{len(close)} close to a single seed of ours (no interval). Claims checked: {len(ctx.claims)} "
        f"({count[SUPPORTED]} supported, {count[NOT_SHOWN]} not shown, {count[CONTRADICTED]} contradicted): a claim is supported "
        "only when the whole 95% interval of its difference is on its side of 0, contradicted when it is wholly on the other."
    )
    if differ:
        lines += ["", "### Numbers that differ", ""]
        for c in differ:
            why = (
                "; ".join(c.reasons)
                if c.reasons
                else "no cause visible in the data (the run looks converged and has an interval)"
            )
            lines.append(
                f"- **{c.section}: {c.what}**: paper {c.paper_value:g} ({c.paper_source}); ours {fmt_ci(c.mean, c.lo, c.hi, c.n, c.digits)}, "
                f"{c.direction}. Why: {why}."
            )
    contradicted = [c for c in ctx.claims if c.verdict == CONTRADICTED]
    not_shown = [c for c in ctx.claims if c.verdict == NOT_SHOWN]
    titles = (
        "Claims our data contradict",
        "Claims our data do not show (an interval that contains 0, one seed, or data missing)",
    )
    for title, checks in zip(titles, (contradicted, not_shown)):
        if checks:
            lines += ["", f"### {title}", ""]
        for c in checks:
            why = "quick plan (short runs): not a test of the claim" if ctx.quick(c.game) else "see the section's table above"
            missing = f"; missing: {', '.join(c.missing)}" if c.missing else ""
            lines.append(f"- *{c.claim.text}* ({c.scope}): {c.evidence}{missing}. Why: {why}.")
    if ctx.notes:
        lines += ["", "### Absent or partial data, and other differences", ""]
        lines += [f"- {n}" for n in ctx.notes]
    if not differ and not contradicted and not not_shown and not ctx.notes:
        lines += ["", "No difference found."]
    return "\n".join(lines)
