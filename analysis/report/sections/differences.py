"""Section: where ours differs from the paper, and why (the summary built from every other section)."""

from __future__ import annotations

from analysis.report.context import Context
from analysis.report.formatting import fmt_ci


def differences_section(ctx: Context) -> str:
    lines = ["## Where ours differs from the paper, and why", ""]
    inside = [c for c in ctx.comparisons if c.status == "inside"]
    differ = [c for c in ctx.comparisons if c.differs]
    close = [c for c in ctx.comparisons if c.status == "no interval" and not c.differs]
    lines.append(
        f"{len(ctx.comparisons)} paper numbers compared: {len(inside)} inside our 95% interval, {len(differ)} differ, "
        f"{len(close)} close to a single run of ours (no interval). Claims checked: {len(ctx.claims)} "
        f"({sum(c.verdict.startswith('supported') for c in ctx.claims)} supported, {sum(c.verdict.startswith('not shown') for c in ctx.claims)} not shown "
        f"(a lower mean inside overlapping intervals), {sum(c.verdict == 'contradicted' for c in ctx.claims)} contradicted, "
        f"{sum(c.verdict == 'undetermined' for c in ctx.claims)} undetermined)."
    )
    if differ:
        lines += ["", "### Numbers that differ", ""]
        for c in differ:
            why = "; ".join(c.reasons) if c.reasons else "no cause visible in the data (the run looks converged and has an interval)"
            lines.append(
                f"- **{c.section}: {c.what}**: paper {c.paper_value:g} ({c.paper_source}); ours {fmt_ci(c.mean, c.lo, c.hi, c.n, c.digits)}, "
                f"{c.direction}. Why: {why}."
            )
    contradicted = [c for c in ctx.claims if c.verdict == "contradicted"]
    not_shown = [c for c in ctx.claims if c.verdict.startswith("not shown")]
    for title, checks in (("Claims our data contradict", contradicted), ("Claims our data do not show (a lower mean inside overlapping intervals)", not_shown)):
        if checks:
            lines += ["", f"### {title}", ""]
        for c in checks:
            why = "quick plan (short runs): not a test of the claim" if ctx.quick(c.game) else "see the section's table above"
            lines.append(f"- *{c.claim.text}* ({c.scope}): {c.evidence}. Why: {why}.")
    if ctx.notes:
        lines += ["", "### Absent or partial data, and other differences", ""]
        lines += [f"- {n}" for n in ctx.notes]
    if not differ and not contradicted and not not_shown and not ctx.notes:
        lines += ["", "No difference found."]
    return "\n".join(lines)
