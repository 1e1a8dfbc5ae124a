"""Section: self-play populations and cross-play."""

from __future__ import annotations

import numpy as np

from analysis import figures, paper
from analysis.report.context import Context
from analysis.report.formatting import fmt_ci, md_table
from analysis.summaries import mean_ci


def selfplay_section(ctx: Context) -> str:
    lines = ["## Self-play and cross-play", ""]
    if ctx.selfplay.empty and not ctx.crossplay:
        lines.append("No self-play report (populations/*/selfplay_report.csv) or cross-play matrix (crossplay/*.csv) found.")
        return "\n".join(lines)
    if not ctx.selfplay.empty:
        rows = []
        for (game, population, split), g in ctx.selfplay.groupby(["game", "population", "split"]):
            pn = paper.SELFPLAY_PARTNERS.get(game, {}).get(split)
            passed = int(g["passed"].sum())
            note = (
                "" if pn is None else ("as in the paper" if passed == pn.value else f"**differs** from the paper's {pn.value:g}")
            )
            rows.append(
                [
                    population,
                    split,
                    len(g),
                    passed,
                    f"{pn.value:g}" if pn else "—",
                    fmt_ci(*mean_ci(g["steps_to_gate"].astype(float)), 0),
                    note,
                ]
            )
            if pn is not None and passed != pn.value:
                ctx.notes.append(
                    f"self-play {population} ({split}): {passed} partners passed the gate, the paper used {pn.value:g}"
                )
        lines.append(
            md_table(
                [
                    "population",
                    "split",
                    "pairs trained",
                    "passed the gate",
                    "paper's partner count",
                    "env steps to the gate",
                    "note",
                ],
                rows,
            )
        )
        lines += ["", ctx.save(figures.selfplay_heatmap(ctx.selfplay), "selfplay")]
    for stem, matrix in ctx.crossplay.items():
        values = matrix.to_numpy(dtype=float)
        text = f"Cross-play `{stem}`: mean {np.nanmean(values):.3f} over {values.size} pairings"
        if list(matrix.index) == list(matrix.columns):
            diag = np.diag(values)
            off = values[~np.eye(len(values), dtype=bool)]
            text += f"; self-play (diagonal) {diag.mean():.3f}, cross-play (off-diagonal) {off.mean():.3f}"
        lines += ["", text + ".", "", ctx.save(figures.crossplay_heatmap(matrix, title=stem), f"crossplay_{stem}")]
    return "\n".join(lines)
