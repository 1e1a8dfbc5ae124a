"""Section: adapting to a new partner (fig:armsexp, fig:armsexpselfplay, fig:blockshanabiexp) and the paper's claims on it."""

from __future__ import annotations

import pandas as pd

from analysis import figures, paper
from analysis.paper import label_name, population_name
from analysis.report.context import BASELINES, EXTENSIONS, REGULARISED, Context
from analysis.report.formatting import digits, fmt_ci, md_table
from analysis.report.verdicts import ClaimCheck, Comparison, against, claims_block, overall_verdict
from analysis.summaries import adaptation_auc, mean_ci, summarise


def adaptation_claims(ctx: Context, per: pd.DataFrame) -> list[ClaimCheck]:
    """The paper's adaptation claims, checked on `per` (AUC summarised by game, population and label)."""
    checks = []
    claims = {c.key: c for c in paper.ADAPTATION_CLAIMS}
    for population in sorted(per["population"].unique()):
        p = per[per["population"] == population].set_index("label")
        ours = [lab for lab in REGULARISED if lab in p.index]
        base = [lab for lab in BASELINES if lab in p.index]
        scope, game = population_name(population), ctx.game_of_population(population)
        if not ours or not base:
            checks.append(ClaimCheck(claims["regularised-best"], scope, "undetermined", f"needs a regularised method and a baseline; have {', '.join(map(label_name, p.index))}", game))
        else:
            best = max(ours, key=lambda lab: p.at[lab, "mean"])
            outcomes = against(p, best, base)
            evidence = f"best regularised: {label_name(best)} AUC {p.at[best, 'mean']:.3f}; " + ", ".join(f"{label_name(lab)} {p.at[lab, 'mean']:.3f}" for lab in base)
            verdict = overall_verdict(list(outcomes.values()))
            beaten_by = [label_name(lab) for lab, v in outcomes.items() if v in ("tie", "no")]
            if beaten_by:
                evidence += f"; not above {', '.join(beaten_by)}"
            checks.append(ClaimCheck(claims["regularised-best"], scope, verdict, evidence, game))
        if "oracle" in p.index:
            others = [lab for lab in p.index if lab != "oracle" and lab not in EXTENSIONS]
            above = [lab for lab in others if p.at[lab, "mean"] > p.at["oracle", "mean"]]
            verdict = "supported" if not above else "contradicted"
            higher = ", ".join(f"{label_name(x)} {p.at[x, 'mean']:.3f}" for x in above)
            evidence = f"oracle AUC {p.at['oracle', 'mean']:.3f}; " + (f"higher: {higher}" if above else "no method above it")
            checks.append(ClaimCheck(claims["oracle-upper"], scope, verdict, evidence, game))
    for kind in ("hand", "selfplay"):
        pops = [f"bandit-s{m}-{kind}" for m in (2, 3, 4)]
        rows = per[(per["label"] == "modular-lam0.5") & per["population"].isin(pops)].set_index("population")
        present = [x for x in pops if x in rows.index]
        if len(present) < 2:
            continue
        values = [rows.at[x, "mean"] for x in present]
        ok = all(a >= b for a, b in zip(values, values[1:]))
        evidence = " ≥ ".join(f"{population_name(x)} {rows.at[x, 'mean']:.3f}" for x in present) if ok else ", ".join(f"{population_name(x)} {rows.at[x, 'mean']:.3f}" for x in present)
        checks.append(ClaimCheck(claims["fewer-symmetries-easier"], f"ours λ=0.5, {kind} partners", "supported" if ok else "contradicted", "AUC " + evidence, "bandit"))
    return checks


def adaptation_section(ctx: Context) -> str:
    lines = ["## Adapting to a new partner (fig:armsexp, fig:armsexpselfplay, fig:blockshanabiexp)", ""]
    if ctx.adaptation.empty:
        lines.append("No adaptation curves (adaptation/*.csv) found: the adapt stage has not run.")
        ctx.notes.append("adaptation: no curves, so the adaptation claims are undetermined")
        return "\n".join(lines)
    auc = adaptation_auc(ctx.adaptation)
    lines.append(
        "The paper's adaptation figures are images (no numbers in its source); we report per method the return at the first "
        "and last evaluation and the AUC (mean return over all evaluation points, step 0 included), each a mean over the "
        "(seed, test partner) curves with a 95% t-interval. Returns are the exact expectation where the game has one (bandit), "
        "else the mean over the evaluation episodes."
    )
    shown = set()
    for spec in paper.ADAPTATION_FIGURES:
        present = [p.population for p in spec.panels if p.population in set(ctx.adaptation["population"])]
        absent = [p.title for p in spec.panels if p.population not in present]
        lines += ["", f"### {spec.key}: {spec.caption}", ""]
        if absent:
            lines.append(f"Not run (no curves): {', '.join(absent)}.")
            ctx.notes.append(f"{spec.key}: panel(s) {', '.join(absent)} absent")
        if not present:
            continue
        shown.update(present)
        titles = {p.population: p.title for p in spec.panels}
        lines += ["", ctx.save(figures.adaptation_curves(ctx.adaptation, panels=present, titles=titles), spec.key.replace("fig:", "adapt_"))]
    others = sorted(set(ctx.adaptation["population"]) - shown)
    if others:
        lines += ["", f"### Other populations ({', '.join(others)})", "", ctx.save(figures.adaptation_curves(ctx.adaptation, panels=others), "adapt_other")]
    lines += ["", "### Adaptation summary", ""]
    rows = []
    for (game, population, label), g in auc.groupby(["game", "population", "label"]):
        d = digits(game)
        rows.append(
            [
                population_name(population),
                label_name(label),
                g["points"].iloc[0],
                int(g["last_step"].max()),
                fmt_ci(*mean_ci(g["start"]), d),
                fmt_ci(*mean_ci(g["end"]), d),
                fmt_ci(*mean_ci(g["auc"]), d),
                "exact" if g["value_source"].iloc[0] == "exact_return" else "episodes",
            ]
        )
    lines.append(md_table(["population", "method", "points", "last step", "return at step 0", "return at last step", "AUC", "return"], rows))

    # The released code's curves (measured by this project, not the paper) for one setting.
    ref_pop = paper.RELEASED_CODE_POPULATION
    ref = auc[auc["population"] == ref_pop]
    if not ref.empty:
        lines += ["", f"#### {population_name(ref_pop)} beside the authors' released code (measured by this project, `shared/notes/original-code.md`; adaptation to step 240)", ""]
        rows = []
        for label, (start, end) in paper.RELEASED_CODE_ADAPTATION.items():
            g = ref[ref["label"] == label]
            if g.empty:
                rows.append([label_name(label), f"{start.value:g}", "—", f"{end.value:g}", "—", "not run"])
                continue
            last = int(g["last_step"].max())
            c0 = Comparison("adaptation (released code)", f"{population_name(ref_pop)} {label_name(label)}, step 0", start.value, start.source, *mean_ci(g["start"]))
            c1 = Comparison("adaptation (released code)", f"{population_name(ref_pop)} {label_name(label)}, step {last}", end.value, end.source, *mean_ci(g["end"]))
            note = "" if last == 240 else f"our last step is {last}, the reference's 240"
            rows.append([label_name(label), f"{start.value:g}", c0.row()[2], f"{end.value:g}" + (f" ({end.note})" if end.note else ""), c1.row()[2], "; ".join(x for x in (c0.verdict, c1.verdict, note) if x)])
        lines.append(md_table(["method", "released code, step 0", "ours, step 0", "released code, step 240", "ours, last step", "verdict"], rows))

    per = summarise(auc, ["game", "population", "label"], "auc")
    checks = adaptation_claims(ctx, per)
    ctx.claims += checks
    lines += claims_block("adaptation", paper.ADAPTATION_CLAIMS, checks)
    lines += extensions_block(per)
    return "\n".join(lines)


def extensions_block(per: pd.DataFrame) -> list[str]:
    """Markdown lines: each extension of ours (not in the paper) against the baselines, judged as the paper's claim is."""
    rows = []
    for population in sorted(per["population"].unique()):
        p = per[per["population"] == population].set_index("label")
        base = [lab for lab in BASELINES if lab in p.index]
        for label in (lab for lab in sorted(p.index) if lab in EXTENSIONS and base):
            d = digits(p.at[label, "game"])
            ci = {lab: fmt_ci(p.at[lab, "mean"], p.at[lab, "lo"], p.at[lab, "hi"], p.at[lab, "n"], d) for lab in (label, *base)}
            evidence = f"AUC {ci[label]}; " + ", ".join(f"{label_name(lab)} {ci[lab]}" for lab in base)
            rows.append([population_name(population), label_name(label), overall_verdict(list(against(p, label, base).values())), evidence])
    if not rows:
        return []
    return ["", "### Extensions of ours (not in the paper) against the same baselines", "", md_table(["population", "method", "adapts faster than every baseline?", "evidence"], rows), ""]
