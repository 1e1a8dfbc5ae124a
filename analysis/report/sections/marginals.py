"""Section: the task module against the true marginals (fig:marginals)."""

from __future__ import annotations

from analysis import figures, paper
from analysis.paper import label_name, population_name
from analysis.report.context import EXTENSIONS, Context
from analysis.report.formatting import fmt_ci, md_table
from analysis.report.verdicts import ClaimCheck, Comparison, claims_block, compare, overall_verdict
from analysis.summaries import summarise


def marginals_section(ctx: Context) -> str:
    lines = ["## Task module vs the true marginals (fig:marginals)", ""]
    if ctx.marginals.empty:
        lines.append("No marginals.csv found.")
        if any(g in ctx.plans for g in ("bandit", "blocks")):
            ctx.notes.append("marginals: no marginals.csv yet, so fig:marginals is not compared")
        return "\n".join(lines)
    summary = summarise(ctx.marginals, ["game", "population", "label"], "distance")
    summary_all = summarise(ctx.marginals, ["game", "population", "label"], "distance_all_states")
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
        paper_vals = {s: paper.MARGINALS[(r.population, s)] for s, lab in paper.MARGINAL_SERIES.items() if lab == r.label and (r.population, s) in paper.MARGINALS}
        if not paper_vals and r.label in ("agg", "maml"):
            paper_vals = {s: paper.MARGINALS[(r.population, s)] for s in ("L5", "L6") if (r.population, s) in paper.MARGINALS}
        if not paper_vals:
            rows.append([population_name(r.population), label_name(r.label), "—", ours, fmt_ci(r_all["mean"], r_all["lo"], r_all["hi"], r_all["n"]), "no paper number"])
            continue
        # With two candidate baseline bars, compare with the nearer one (the assignment is unknown).
        series, pn = min(paper_vals.items(), key=lambda kv: abs(kv[1].value - r.mean))
        c = Comparison(
            "marginals", f"{population_name(r.population)}, {label_name(r.label)}", pn.value, f"{pn.source} ({series}: {pn.note})", r.mean, r.lo, r.hi, r.n, higher_is_better=False
        )
        if c.differs:
            c.reasons = ctx.reasons(r.game, r.population, r.label, r.n)
            if series in ("L3", "L5", "L6"):
                c.reasons.append(f"the paper's bar {series} is identified by inference only ({pn.note})")
        ctx.comparisons.append(c)
        paper_text = " or ".join(f"{v.value:g} ({s})" for s, v in paper_vals.items())
        rows.append([population_name(r.population), label_name(r.label), paper_text, ours, fmt_ci(r_all["mean"], r_all["lo"], r_all["hi"], r_all["n"]), c.verdict])
    lines.append(md_table(["population", "method", "paper", "ours", "ours, all states", "verdict"], rows))
    ran = set(zip(summary["population"], summary["label"]))
    missing = sorted(
        {f"{population_name(p)} {label_name(lab)}" for (p, s) in paper.MARGINALS for lab in [paper.MARGINAL_SERIES[s]] if lab and (p, lab) not in ran and p.split("-")[0] in ctx.plans}
    )
    if missing:
        lines += ["", f"Paper bars without a result of ours: {', '.join(missing)}."]
    markers = {(p, lab): v.value for (p, s), v in paper.MARGINALS.items() for lab in [paper.MARGINAL_SERIES[s]] if lab}
    lines += ["", ctx.save(figures.marginal_bars(ctx.marginals, markers), "marginals")]
    checks = []
    claims = {c.key: c for c in paper.MARGINAL_CLAIMS}
    for population in sorted(summary["population"].unique()):
        s = summary[summary["population"] == population].set_index("label")
        scope, game = population_name(population), ctx.game_of_population(population)
        paper_methods = s.drop(index=list(EXTENSIONS), errors="ignore")
        if "modular-lam0.5" in s.index and len(paper_methods) > 1:
            best = paper_methods["mean"].idxmin()
            verdict = "supported" if best == "modular-lam0.5" else "contradicted"
            checks.append(ClaimCheck(claims["lam05-closest"], scope, verdict, ", ".join(f"{label_name(lab)} {v:.3f}" for lab, v in paper_methods["mean"].sort_values().items()), game))
        base = [lab for lab in ("agg", "maml") if lab in s.index]
        if "modular-lam0" in s.index and base:
            a = (s.at["modular-lam0", "mean"], s.at["modular-lam0", "lo"], s.at["modular-lam0", "hi"])
            # Lower is better here: "better" means the baseline's distance exceeds λ=0's.
            outcomes = [compare((s.at[b, "mean"], s.at[b, "lo"], s.at[b, "hi"]), a) for b in base]
            verdict = overall_verdict(outcomes)
            checks.append(ClaimCheck(claims["lam0-below-baselines"], scope, verdict, f"λ=0.0 {a[0]:.3f}; " + ", ".join(f"{label_name(b)} {s.at[b, 'mean']:.3f}" for b in base), game))
    ctx.claims += checks
    lines += claims_block("the marginals", paper.MARGINAL_CLAIMS, checks)
    return "\n".join(lines)
