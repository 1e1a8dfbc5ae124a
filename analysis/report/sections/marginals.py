"""Section: the task module against the true marginals (fig:marginals)."""

from __future__ import annotations

from analysis import figures, paper
from analysis.paper import label_name, population_name
from analysis.report.context import Context
from analysis.report.formatting import fmt_ci, md_table
from analysis.report.verdicts import ClaimCheck, Comparison, beats_all, claims_block, variants_block
from analysis.summaries import seed_summary
from rllib_conv.common.methods import LAM0, PAPER_METHOD

# The methods the paper's marginal claims are about: ours λ=0.5, λ=0.0 (named by its caption) and the
# baselines with an estimate of the marginals; λ=0.3, low-dim z and the rest are variants.
MARGINAL_BASELINES = ("agg", "maml")
CLAIMED = (PAPER_METHOD, LAM0, *MARGINAL_BASELINES)


def marginals_section(ctx: Context) -> str:
    lines = ["## Task module vs the true marginals (fig:marginals)", ""]
    if ctx.marginals.empty:
        lines.append("No marginals.csv found.")
        if any(g in ctx.plans for g in ("bandit", "blocks")):
            ctx.notes.append("marginals: no marginals.csv yet, so fig:marginals is not compared")
        return "\n".join(lines)
    summary = seed_summary(ctx.marginals, ["game", "population", "label"], "distance")
    summary_all = seed_summary(ctx.marginals, ["game", "population", "label"], "distance_all_states")
    lines.append(
        "L1 distance between the task module's action distribution (the whole network's for BaselineAgg and MAML) and the "
        "uniform distribution over optimal actions, averaged over the states with more than one optimal action (the paper's "
        "definition; the last column averages over every state). Mean over seeds with 95% interval. The paper's legend is an "
        "image missing from its source: λ=0.0 and λ=0.5 are named by its text, its third bar is most likely λ=0.3, and its "
        "last two bars are the two baselines in an unknown order, so ours are compared with whichever is nearer."
    )
    lines.append("")
    rows = []
    for r in summary.itertuples():
        r_all = summary_all[(summary_all["population"] == r.population) & (summary_all["label"] == r.label)].iloc[0]
        ours = fmt_ci(r.mean, r.lo, r.hi, r.n)
        paper_vals = {
            s: paper.MARGINALS[(r.population, s)]
            for s, lab in paper.MARGINAL_SERIES.items()
            if lab == r.label and (r.population, s) in paper.MARGINALS
        }
        if not paper_vals and r.label in ("agg", "maml"):
            paper_vals = {s: paper.MARGINALS[(r.population, s)] for s in ("L5", "L6") if (r.population, s) in paper.MARGINALS}
        if not paper_vals:
            rows.append(
                [
                    population_name(r.population),
                    label_name(r.label),
                    "—",
                    ours,
                    fmt_ci(r_all["mean"], r_all["lo"], r_all["hi"], r_all["n"]),
                    "no paper number",
                ]
            )
            continue
        # With two candidate baseline bars, compare with the nearer one (the assignment is unknown).
        series, pn = min(paper_vals.items(), key=lambda kv: abs(kv[1].value - r.mean))
        c = Comparison(
            "marginals",
            f"{population_name(r.population)}, {label_name(r.label)}",
            pn.value,
            f"{pn.source} ({series}: {pn.note})",
            r.mean,
            r.lo,
            r.hi,
            r.n,
            higher_is_better=False,
        )
        if c.differs:
            c.reasons = ctx.reasons(r.game, r.population, r.label, r.n)
            if series in ("L3", "L5", "L6"):
                c.reasons.append(f"the paper's bar {series} is identified by inference only ({pn.note})")
        ctx.comparisons.append(c)
        paper_text = " or ".join(f"{v.value:g} ({s})" for s, v in paper_vals.items())
        rows.append(
            [
                population_name(r.population),
                label_name(r.label),
                paper_text,
                ours,
                fmt_ci(r_all["mean"], r_all["lo"], r_all["hi"], r_all["n"]),
                c.verdict,
            ]
        )
    lines.append(md_table(["population", "method", "paper", "ours", "ours, all states", "verdict"], rows))
    ran = set(zip(summary["population"], summary["label"]))
    missing = sorted(
        {
            f"{population_name(p)} {label_name(lab)}"
            for (p, s) in paper.MARGINALS
            for lab in [paper.MARGINAL_SERIES[s]]
            if lab and (p, lab) not in ran and p.split("-")[0] in ctx.plans
        }
    )
    if missing:
        lines += ["", f"Paper bars without a result of ours: {', '.join(missing)}."]
    markers = {(p, lab): v.value for (p, s), v in paper.MARGINALS.items() for lab in [paper.MARGINAL_SERIES[s]] if lab}
    caption = (
        figures.band_caption(ctx.marginals, "Bars: mean over seeds (values printed on them); error bars", averaged=None)
        + " Crosses: the paper's bars."
    )
    lines += ["", ctx.save(figures.marginal_bars(ctx.marginals, markers), "marginals", caption)]
    checks = []
    claims = {c.key: c for c in paper.MARGINAL_CLAIMS}
    for population in sorted(ctx.marginals["population"].unique()):
        p = ctx.marginals[ctx.marginals["population"] == population]
        labels = set(p["label"])
        scope, game = population_name(population), ctx.game_of_population(population)
        # One distance per trained ego: methods are paired on the seed alone; smaller is better.
        others = [lab for lab in (LAM0, *MARGINAL_BASELINES) if lab in labels]
        if PAPER_METHOD in labels and others:
            verdict, evidence = beats_all(p, PAPER_METHOD, others, "distance", (), lower_is_better=True)
            checks.append(ClaimCheck(claims["lam05-closest"], scope, verdict, "distance " + evidence, game))
        base = [lab for lab in MARGINAL_BASELINES if lab in labels]
        if LAM0 in labels and base:
            verdict, evidence = beats_all(p, LAM0, base, "distance", (), lower_is_better=True)
            checks.append(ClaimCheck(claims["lam0-below-baselines"], scope, verdict, "distance " + evidence, game))
    ctx.claims += checks
    rule = (
        'A claim "A is closer to the true marginals than B" is judged on the paired difference of distances B − A over the '
        "seeds both share, with its 95% t-interval over seeds: supported when the whole interval is above 0, contradicted when "
        "it is below 0, not shown otherwise (or with one seed). λ=0.3 and the other variants are in a table of their own."
    )
    lines += claims_block("the marginals", paper.MARGINAL_CLAIMS, checks, rule)
    lines += variants_block(
        ctx.marginals,
        "distance",
        (),
        CLAIMED,
        MARGINAL_BASELINES,
        "closer to the true marginals than every baseline?",
        lower_is_better=True,
        places=3,
    )
    return "\n".join(lines)
