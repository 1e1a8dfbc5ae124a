"""Section: the field's protocol, the `evaluate` stage (every method's egos against the game's evaluation sets).

Read from `<game>/evaluation/<population>__<role>/summary.json` (`rllib-conv evaluate`): per
method the mean and the IQM of the normalised scores (return / the partner's best-response
bound, exact or as the set declares) with their bootstrap intervals over seeds. Empty where
no plan ran the stage, so reports of plans without it are unchanged.
"""

from __future__ import annotations

from analysis.paper import label_name, population_name
from analysis.report.context import Context
from analysis.report.formatting import fmt_ci, md_table


def evaluation_section(ctx: Context) -> str:
    """One table per (game, population, set): each method's mean and IQM normalised score; empty if none was run."""
    if ctx.evaluations.empty:
        return ""
    lines = [
        "## The field's protocol: evaluation sets",
        "",
        "Every method's egos, as trained (no adaptation; a modular ego's task module, the one head of the others), against "
        "every partner of the game's shipped evaluation set (with several partner seats, every team of them), as "
        "`rllib-conv evaluate` scores them (docs/protocol.md): the normalised score is the return over the partner's "
        "best-response bound, exact where the game has one, else the bound the set declares (a trained best response: "
        "not an upper bound, so a score can exceed 1). Mean and IQM (25% trimmed) of every (seed, partner) score, with "
        "95% percentile bootstrap intervals that resample seeds.",
    ]
    for (game, population, name, bounds), frame in ctx.evaluations.groupby(["game", "population", "set", "bounds"], sort=False):
        rows = [
            [
                label_name(r["label"]),
                fmt_ci(r["mean"], r["mean_low"], r["mean_high"], r["seeds"]),
                fmt_ci(r["iqm"], r["iqm_low"], r["iqm_high"], r["seeds"]),
                r["partners"],
                f"{r['return']:.3f}",
            ]
            for r in frame.to_dict("records")
        ]
        lines += [
            "",
            f"### {game}: {population_name(population)} egos against `{name}` ({bounds} bounds)",
            "",
            md_table(["method", "mean normalised [95% CI]", "IQM normalised [95% CI]", "partners", "mean return"], rows),
        ]
    return "\n".join(lines) + "\n"
