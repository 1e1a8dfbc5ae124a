"""Section: adapting to a new partner (fig:armsexp, fig:armsexpselfplay, fig:blockshanabiexp) and the paper's claims on it."""

from __future__ import annotations

import pandas as pd

from analysis import figures, paper
from analysis.paper import information_used, label_name, population_name
from analysis.report.context import Context
from analysis.report.formatting import digits, fmt_summary, md_table
from analysis.report.verdicts import (
    ClaimCheck,
    Comparison,
    Difference,
    all_hold,
    beats_all,
    beats_every,
    claims_block,
    variants_block,
)
from analysis.summaries import adaptation_auc, seed_summary, unit_means, unpaired_difference
from rllib_conv.common.methods import BASELINES, PAPER_METHOD, SCRATCH

# The labels the paper's adaptation claims are about; every other label is a variant of ours.
CLAIMED = (PAPER_METHOD, *BASELINES, "oracle", SCRATCH)
WITHIN = ("partner",)  # an AUC is paired on (seed, test partner)


def adaptation_claims(ctx: Context, auc: pd.DataFrame) -> list[ClaimCheck]:
    """The paper's adaptation claims, checked on `auc` (one row per curve) by paired differences over seeds."""
    checks = []
    claims = {c.key: c for c in paper.ADAPTATION_CLAIMS}
    for population in sorted(auc["population"].unique()):
        p = auc[auc["population"] == population]
        labels = set(p["label"])
        scope, game = population_name(population), ctx.game_of_population(population)
        places = digits(game)
        # The claim names all three baselines: with one missing it is not shown (missing: ...), never supported on the rest.
        best = beats_every(p, PAPER_METHOD, BASELINES, "auc", WITHIN, places)
        checks.append(ClaimCheck.of(claims["regularised-best"], scope, best, game, "AUC "))
        others = [lab for lab in CLAIMED if lab in labels and lab != "oracle"]
        if "oracle" in labels and others:
            verdict, evidence = beats_all(p, "oracle", others, "auc", WITHIN, places)
            checks.append(ClaimCheck(claims["oracle-upper"], scope, verdict, "AUC " + evidence, game))
    ours = unit_means(auc[auc["label"] == PAPER_METHOD], ["population"], "auc")  # seeds, or populations where pooled
    for kind in ("hand", "selfplay"):
        named = [f"bandit-s{m}-{kind}" for m in (2, 3, 4)]
        present = [x for x in named if x in set(ours["population"])]
        if len(present) < 2:
            continue
        # "Arms 2 easier than Arms 3 easier than Arms 4" names all three: one missing leaves it not shown.
        missing = tuple(population_name(x) for x in named if x not in present)
        # Different populations share no test partners: their seed means are compared unpaired (Welch).
        seeds = {x: ours.loc[ours["population"] == x, "auc"] for x in present}
        diffs = [
            Difference(population_name(x), population_name(y), *unpaired_difference(seeds[x], seeds[y]))
            for x, y in zip(present, present[1:])
        ]
        verdict = all_hold((d.verdict for d in diffs), missing)
        checks.append(
            ClaimCheck(
                claims["fewer-symmetries-easier"],
                f"ours λ=0.5, {kind} partners",
                verdict,
                "AUC " + "; ".join(d.text() for d in diffs),
                "bandit",
                missing,
            )
        )
    return checks


def summary_table(auc: pd.DataFrame) -> str:
    """Per population and method: the return at the first and last evaluation, the AUC and the gain over not adapting, each with its seed-level interval.

    The gain is AUC − return at step 0, per curve: what adapting earned over holding the ego as it was (a frozen
    ego scores its step-0 return at every point, in expectation), so a negative gain means adapting cost return. The
    last column says what each method's adapter reads besides the trained ego (`paper.information_used`).
    """
    keys = ["game", "population", "label"]
    auc = auc.assign(gain=auc["auc"] - auc["start"])
    start, end, area, gain = (seed_summary(auc, keys, column).set_index(keys) for column in ("start", "end", "auc", "gain"))
    rows = []
    for (game, population, label), g in auc.groupby(keys):
        d, key = digits(game), (game, population, label)
        cells = [fmt_summary(s.loc[key], d) for s in (start, end, area, gain)]
        source = "exact" if g["value_source"].iloc[0] == "exact_return" else "episodes"
        rows.append(
            [
                population_name(population),
                label_name(label),
                g["points"].iloc[0],
                int(g["last_step"].max()),
                g["partner"].nunique(),
                *cells,
                source,
                information_used(label),
            ]
        )
    return md_table(
        [
            "population",
            "method",
            "points",
            "last step",
            "test partners",
            "return at step 0",
            "return at last step",
            "AUC",
            "gain over not adapting (AUC − step 0)",
            "return",
            "information used",
        ],
        rows,
    )


def released_code_table(auc: pd.DataFrame) -> list[str]:
    """Markdown lines: our curves on the released code's setting beside its measured start and end (empty without them)."""
    ref_pop = paper.RELEASED_CODE_POPULATION
    ref = auc[auc["population"] == ref_pop]
    if ref.empty:
        return []
    lines = [
        "",
        f"#### {population_name(ref_pop)} beside the authors' released code (measured by this project, docs/differences.md; adaptation to step 240)",
        "",
    ]
    rows = []
    for label, (start, end) in paper.RELEASED_CODE_ADAPTATION.items():
        g = ref[ref["label"] == label]
        if g.empty:
            rows.append([label_name(label), f"{start.value:g}", "—", f"{end.value:g}", "—", "not run"])
            continue
        last = int(g["last_step"].max())
        what = f"{population_name(ref_pop)} {label_name(label)}"
        s0, s1 = (seed_summary(g, ["label"], column).iloc[0] for column in ("start", "end"))
        c0 = Comparison(
            "adaptation (released code)",
            f"{what}, step 0",
            start.value,
            start.source,
            s0["mean"],
            s0["lo"],
            s0["hi"],
            int(s0["n"]),
        )
        c1 = Comparison(
            "adaptation (released code)",
            f"{what}, step {last}",
            end.value,
            end.source,
            s1["mean"],
            s1["lo"],
            s1["hi"],
            int(s1["n"]),
        )
        note = "" if last == 240 else f"our last step is {last}, the reference's 240"
        rows.append(
            [
                label_name(label),
                f"{start.value:g}",
                c0.row()[2],
                f"{end.value:g}" + (f" ({end.note})" if end.note else ""),
                c1.row()[2],
                "; ".join(x for x in (c0.verdict, c1.verdict, note) if x),
            ]
        )
    return lines + [
        md_table(
            ["method", "released code, step 0", "ours, step 0", "released code, step 240", "ours, last step", "verdict"], rows
        )
    ]


def adaptation_section(ctx: Context) -> str:
    lines = ["## Adapting to a new partner (fig:armsexp, fig:armsexpselfplay, fig:blockshanabiexp)", ""]
    if ctx.adaptation.empty:
        lines.append("No adaptation curves (adaptation/*.csv) found: the adapt stage has not run.")
        ctx.notes.append("adaptation: no curves, so the adaptation claims are not shown")
        return "\n".join(lines)
    auc = adaptation_auc(ctx.adaptation)
    lines.append(
        "The paper's adaptation figures are images (no numbers in its source); we report per method the return at the first "
        "and last evaluation and the AUC (mean return over all evaluation points, step 0 included). Each is averaged per seed "
        "over its test partners, then over seeds, with a 95% t-interval over seeds (n = seeds). Returns are the exact "
        "expectation where the game has one (bandit), else the mean over the evaluation episodes."
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
        part = ctx.adaptation[ctx.adaptation["population"].isin(present)]
        fig = figures.adaptation_curves(ctx.adaptation, panels=present, titles=titles)
        lines += [
            "",
            ctx.save(fig, spec.key.replace("fig:", "adapt_"), figures.band_caption(part, "Lines: mean over seeds; bands")),
        ]
    others = sorted(set(ctx.adaptation["population"]) - shown)
    if others:
        part = ctx.adaptation[ctx.adaptation["population"].isin(others)]
        fig = figures.adaptation_curves(ctx.adaptation, panels=others)
        lines += [
            "",
            f"### Other populations ({', '.join(others)})",
            "",
            ctx.save(fig, "adapt_other", figures.band_caption(part, "Lines: mean over seeds; bands")),
        ]
    lines += ["", "### Adaptation summary", "", summary_table(auc)]
    lines += released_code_table(auc)

    checks = adaptation_claims(ctx, auc)
    ctx.claims += checks
    rule = (
        f'Checked on the paper\'s own method ({label_name(PAPER_METHOD)}) alone. A claim "A adapts faster than B" is judged '
        "on the paired AUC difference A − B over the (seed, test partner) units both share, averaged per seed, with its 95% "
        "t-interval over seeds: supported when the whole interval is above 0, contradicted when it is below 0, not shown "
        "otherwise (or with one seed). A claim over several methods needs every one it names: with one missing it is not shown "
        "(missing: ...) unless a present one contradicts it. Populations share no partners, so Arms m against Arms m+1 is Welch's unpaired "
        "interval over seed means."
    )
    lines += claims_block("adaptation", paper.ADAPTATION_CLAIMS, checks, rule)
    lines += variants_block(auc, "auc", WITHIN, CLAIMED, BASELINES, "adapts faster than every baseline?")
    return "\n".join(lines)
