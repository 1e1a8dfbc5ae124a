"""Section: training the egos (final returns with the training partners, training curves)."""

from __future__ import annotations

import pandas as pd

from analysis import figures, loaders
from analysis.paper import label_name, population_name
from analysis.report.context import Context
from analysis.report.formatting import digits, fmt_ci, md_table


def training_section(ctx: Context) -> str:
    lines = ["## Training the egos", ""]
    if ctx.training.empty:
        lines.append("No training logs (runs/<population>__<label>/*/progress.csv) found.")
        return "\n".join(lines)
    lines.append(
        "Final return of each trained ego with its training partners (eval.json: `run.eval_episodes` episodes per partner, 200 unless the "
        "plan's train_overrides set fewer; the exact expectation on the bandit), averaged per seed over its training partners, then over "
        "seeds with a 95% t-interval over seeds (n = seeds); the game's maximum beside it (— where the game states none)."
    )
    lines.append("")
    rows = []
    for r in ctx.train_summary.itertuples():
        top = loaders.max_score(ctx.plans.get(r.game, {"game": r.game}))
        rows.append(
            [
                r.game,
                population_name(r.population),
                label_name(r.label),
                fmt_ci(r.mean, r.lo, r.hi, r.n, digits(r.game)),
                "—" if pd.isna(top) else f"{top:g}",  # no stated maximum (Overcooked)
            ]
        )
    lines.append(md_table(["game", "population", "method", "final training return", "max"], rows))
    for game in sorted(ctx.training["game"].unique()):
        part = ctx.training[ctx.training["game"] == game]
        caption = figures.band_caption(
            part, "Lines: return_mean against training env steps, mean over seeds; bands", averaged=None
        )
        lines += ["", f"Training curves, {game}:", "", ctx.save(figures.training_curves(part), f"training_{game}", caption)]
    return "\n".join(lines)
