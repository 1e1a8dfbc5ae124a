"""The report's first section: what was found under the root (games, stages, trials, env steps)."""

from __future__ import annotations

import pandas as pd

from analysis import loaders
from analysis.paper import label_name
from analysis.populations import GROUPS_KEY
from analysis.report.context import Context
from analysis.report.formatting import md_table
from rllib_conv.common.methods import EXTENSIONS


def trained_steps(curves: pd.DataFrame) -> str:
    """The env steps the trials of `curves` trained for: one number, or the range over trials."""
    if curves.empty or "steps" not in curves:
        return "—"
    last = curves.groupby("run")["steps"].max().dropna()
    if last.empty:
        return "—"
    low, high = int(last.min()), int(last.max())
    return f"{low:,}" if low == high else f"{low:,}–{high:,}"


def status_section(ctx: Context) -> str:
    lines = ["## What was found", ""]
    if not ctx.games:
        lines.append(
            f"No game folder (plan.json, runs/, adaptation/, ...) under `{ctx.root}`: nothing to report but the user study."
        )
        return "\n".join(lines)
    rows = []
    for game_dir in ctx.games:
        game = loaders.game_of(game_dir)
        plan = ctx.plans[game]
        st = ctx.stages[ctx.stages["game"] == game]
        done = [f"{r.stage} ({r.seconds:.0f} s)" for r in st.itertuples() if r.done]
        missing = [r.stage for r in st.itertuples() if r.expected and not r.done]
        curves = ctx.training[ctx.training["game"] == game] if not ctx.training.empty else ctx.training
        trials = curves["run"].nunique() if not curves.empty else 0
        rows.append(
            [
                game,
                f"`{game_dir.name}`",  # under the root the report names above: the report reads the same rebuilt elsewhere
                plan.get("seeds", "?"),
                "yes" if plan.get("quick") else "no",
                ", ".join(done) or "none",
                ", ".join(missing) or "none",
                trials,
                trained_steps(curves),
            ]
        )
        if missing:
            ctx.notes.append(f"{game}: stage(s) not finished: {', '.join(missing)} (their results are partial or absent below)")
    lines.append(
        md_table(
            [
                "game",
                "folder",
                "seeds",
                "quick",
                "stages done (wall time, all runs on the folder)",
                "stages not done",
                "trained-ego trials with logs",
                "env steps per ego",
            ],
            rows,
        )
    )
    lines += seeds_and_populations(ctx)
    for game in loaders.MAX_SCORE:
        if game not in ctx.plans:
            ctx.notes.append(f"{game}: no folder under the root; its figures and numbers are skipped")
    labels = {
        lab for frame in (ctx.training, ctx.adaptation, ctx.zeroshot, ctx.marginals) if not frame.empty for lab in frame["label"]
    }
    for label in sorted(labels & set(EXTENSIONS)):
        ctx.notes.append(
            f"{label_name(label)} (`{label}`) is not in the paper: it is listed in the tables without a paper number and left out of the paper's claims"
        )
    return "\n".join(lines)


def seeds_and_populations(ctx: Context) -> list[str]:
    """Lines on the seeds each plan declared before the run (flagged where the run has fewer) and on pooled populations.

    Nothing for a folder whose plan.json declares no seeds and pools no populations (earlier runs).
    """
    lines = []
    for game, plan in ctx.plans.items():
        declared, run = plan.get("declared_seeds"), len(plan.get("seeds", []))
        if declared is not None:
            fewer = run < declared and not plan.get("quick")
            flag = f" **Fewer than declared: every claim below is judged on {run} of the {declared} seeds it needs.**"
            lines.append(
                f"- {game}: the plan declared {declared} seeds per claim before the run; this run has {run}.{flag if fewer else ''}"
            )
            if fewer:
                ctx.notes.append(f"{game}: {run} seeds run of the {declared} the plan declared its claims need")
        for kind, members in sorted(plan.get(GROUPS_KEY, {}).items()):
            lines.append(
                f"- {game}: `{kind}` pools {len(members)} independently trained self-play populations "
                f"({', '.join(f'`{m}`' for m in members)}): each seed is averaged over its test partners, the seeds within "
                "each population, and its intervals are over the population means (n = populations)."
            )
    return ["", *lines] if lines else []
