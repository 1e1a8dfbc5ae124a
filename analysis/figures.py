"""The report's figures: each function takes a tidy DataFrame (from `analysis.loaders`) and returns a matplotlib Figure.

Nothing here reads files or shows windows; `save` writes a figure as PNG and PDF.
Means are over units (seed x test-partner curves, or seeds) with 95% t-intervals drawn
as bands or error bars (see `analysis.summaries`); a group with one unit has no band.
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

import matplotlib

matplotlib.use("Agg")  # files only: no display on servers and CI
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from analysis.paper import label_name, population_name  # noqa: E402
from analysis.summaries import curve_band, summarise, with_value  # noqa: E402

# Methods in the order of the paper's legends; colours follow the paper's bar charts where it
# has them (L1 red = λ 0.0, L3 salmon, L4 orange = λ 0.5, grey baselines, green oracle).
LABEL_ORDER: tuple[str, ...] = ("modular-lam0", "modular-lam0.3", "modular-lam0.5", "modular-lam0.5-hl0.01", "modular-lam0.5-pick", "modular-lam0.5-hl0.01-pick", "lowz-lam0.5", "agg", "no_task_logits", "maml", "oracle", "scratch")
LABEL_COLOURS: dict[str, tuple[float, float, float] | str] = {
    "modular-lam0": (0.6627, 0.1608, 0.1804),
    "modular-lam0.3": (0.9608, 0.5020, 0.5098),
    "modular-lam0.5": (1.0000, 0.6471, 0.1765),
    "modular-lam0.5-hl0.01": "tab:brown",  # not in the paper
    "modular-lam0.5-pick": "tab:pink",  # not in the paper
    "modular-lam0.5-hl0.01-pick": "tab:olive",  # not in the paper
    "lowz-lam0.5": "tab:purple",
    "agg": (0.4118, 0.4118, 0.4118),
    "no_task_logits": (0.6627, 0.6627, 0.6627),
    "maml": "tab:blue",
    "oracle": "tab:green",
    "scratch": "black",
}
TASK_COLOURS = {"train": "0.8", "test": (1.0, 0.5, 0.0)}  # the paper's grey and orange bars


def ordered_labels(labels: Sequence[str]) -> list[str]:
    """`labels` (unique) in the paper's legend order, unknown ones last in name order."""
    known = [x for x in LABEL_ORDER if x in set(labels)]
    return known + sorted(set(labels) - set(LABEL_ORDER))


def colour(label: str) -> object:
    """The plotting colour of a method label."""
    return LABEL_COLOURS.get(label, "tab:cyan")


def save(fig: Figure, path_stem: str | Path, dpi: int = 130) -> tuple[Path, Path]:
    """Write `fig` as `<path_stem>.png` and `<path_stem>.pdf` (folders created), close it, and return both paths."""
    stem = Path(path_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    png, pdf = stem.with_name(stem.name + ".png"), stem.with_name(stem.name + ".pdf")
    fig.savefig(png, dpi=dpi, bbox_inches="tight")
    # No creation date: a rebuilt report leaves unchanged figures byte-identical (no git churn).
    fig.savefig(pdf, bbox_inches="tight", metadata={"CreationDate": None})
    plt.close(fig)
    return png, pdf


def _grid(n: int, ncols: int, size: tuple[float, float] = (4.0, 3.0)) -> tuple[Figure, list[plt.Axes]]:
    ncols = max(1, min(ncols, n))
    nrows = max(1, -(-n // ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(size[0] * ncols, size[1] * nrows), squeeze=False)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def _legend_below(fig: Figure, axes: Sequence[plt.Axes]) -> None:
    handles, labels = {}, {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles[lab], labels[lab] = h, lab
    fig.tight_layout()
    if handles:
        # Below the figure, whatever its rows: `save` crops to the drawn content, legend included.
        fig.legend(list(handles.values()), list(labels.values()), loc="upper center", ncol=min(5, len(handles)), frameon=False, bbox_to_anchor=(0.5, 0.0))


def _band_plot(ax: plt.Axes, band: pd.DataFrame, x: str) -> None:
    """One line per label with its 95% band (`band` has columns label, x, mean, lo, hi)."""
    for label in ordered_labels(band["label"].unique()):
        part = band[band["label"] == label].sort_values(x)
        style = "--" if label == "scratch" else "-"
        ax.plot(part[x], part["mean"], style, color=colour(label), label=label_name(label), lw=1.6)
        has_ci = part["lo"].notna()
        if has_ci.any():
            ax.fill_between(part.loc[has_ci, x], part.loc[has_ci, "lo"], part.loc[has_ci, "hi"], color=colour(label), alpha=0.18, lw=0)


def adaptation_curves(
    curves: pd.DataFrame, panels: Sequence[str] | None = None, titles: Mapping[str, str] | None = None, ncols: int = 4, title: str | None = None
) -> Figure:
    """Adaptation to a new partner (the paper's fig:armsexp / fig:armsexpselfplay / fig:blockshanabiexp).

    `curves` is `loaders.load_adaptation`'s frame. One panel per population (`panels`
    picks and orders them; default all, by name), one line per method label: mean return
    over every (seed, test partner) curve at each adaptation step, with its 95% band.
    Returns the Figure.
    """
    populations = list(panels) if panels is not None else sorted(curves["population"].unique())
    fig, axes = _grid(max(1, len(populations)), ncols)
    band = curve_band(curves)
    for ax, population in zip(axes, populations):
        _band_plot(ax, band[band["population"] == population], "steps")
        ax.set_title((titles or {}).get(population, population_name(population)), fontsize=10)
        ax.set_xlabel("adaptation env steps")
        ax.set_ylabel("return")
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    _legend_below(fig, axes)
    return fig


def training_curves(training: pd.DataFrame, metric: str = "return_mean", panels: Sequence[str] | None = None, ncols: int = 4) -> Figure:
    """Training return against env steps: one panel per population, one line per label, 95% band over seeds.

    `training` is `loaders.load_training`'s frame; `metric` one of its columns. Seeds
    are aligned on `training_iteration`, their steps averaged. Returns the Figure.
    """
    populations = list(panels) if panels is not None else sorted(training["population"].unique())
    fig, axes = _grid(max(1, len(populations)), ncols)
    if not training.empty and metric in training.columns:
        band = summarise(training.dropna(subset=[metric]), ["population", "label", "training_iteration"], metric)
        steps = training.groupby(["population", "label", "training_iteration"])["steps"].mean().rename("steps").reset_index()
        band = band.merge(steps, on=["population", "label", "training_iteration"])
        for ax, population in zip(axes, populations):
            _band_plot(ax, band[band["population"] == population], "steps")
    for ax, population in zip(axes, populations):
        ax.set_title(population_name(population), fontsize=10)
        ax.set_xlabel("training env steps")
        ax.set_ylabel(metric)
        ax.grid(alpha=0.3)
    _legend_below(fig, axes)
    return fig


def _grouped_bars(
    ax: plt.Axes, summary: pd.DataFrame, groups: Sequence[str], paper: Mapping[tuple[str, str], float] | None, paper_label: str
) -> None:
    """Bars of `summary` (group, label, mean, lo, hi) grouped by `groups`, one colour per label; paper values as black markers."""
    labels = ordered_labels(summary["label"].unique())
    width = 0.8 / max(1, len(labels))
    marked = False
    for j, label in enumerate(labels):
        xs, heights, errs = [], [], [[], []]
        for i, group in enumerate(groups):
            row = summary[(summary["group"] == group) & (summary["label"] == label)]
            if row.empty:
                continue
            r = row.iloc[0]
            x = i - 0.4 + width * (j + 0.5)
            xs.append(x)
            heights.append(r["mean"])
            errs[0].append(r["mean"] - r["lo"] if np.isfinite(r["lo"]) else 0.0)
            errs[1].append(r["hi"] - r["mean"] if np.isfinite(r["hi"]) else 0.0)
            if paper and (group, label) in paper:
                ax.plot([x], [paper[(group, label)]], marker="x", color="black", ms=7, mew=2, ls="none", label=paper_label if not marked else None)
                marked = True
        if xs:
            ax.bar(xs, heights, width=width * 0.95, color=colour(label), label=label_name(label), yerr=errs, capsize=2, edgecolor="black", lw=0.4)
    ax.set_xticks(range(len(groups)), [population_name(g) for g in groups], fontsize=8)
    ax.grid(axis="y", alpha=0.3)


def marginal_bars(marginals: pd.DataFrame, paper: Mapping[tuple[str, str], float] | None = None) -> Figure:
    """Distance between each task module and the true marginals (the paper's fig:marginals).

    `marginals` is `loaders.load_marginals`'s frame: bars per population (groups) and
    method label, height = mean `distance` over seeds with 95% error bars. `paper` maps
    (population, label) to the paper's value, drawn as black crosses. Returns the Figure.
    """
    fig, ax = plt.subplots(figsize=(max(5.0, 1.6 * max(1, marginals["population"].nunique()) + 3), 3.4))
    summary = summarise(marginals, ["population", "label"], "distance").rename(columns={"population": "group"})
    _grouped_bars(ax, summary, sorted(summary["group"].unique()), paper, "paper")
    ax.set_ylabel("L1 distance to true marginals")
    ax.set_title("task module vs true marginals (lower is better)", fontsize=10)
    _legend_below(fig, [ax])
    return fig


def zeroshot_bars(zeroshot: pd.DataFrame, paper: Mapping[tuple[str, str], float] | None = None) -> Figure:
    """Zero-shot return on the new task with the test partners (the paper's fig:zeroshot).

    `zeroshot` is `loaders.load_zeroshot`'s frame. One panel per game (their score scales
    differ), bars per population and method label: mean over (seed, test partner) of the
    exact return where known, else the evaluated mean, with 95% error bars; `paper`
    values as black crosses. Returns the Figure.
    """
    games = sorted(zeroshot["game"].unique()) if not zeroshot.empty else ["(none)"]
    fig, axes = _grid(len(games), len(games), size=(5.0, 3.4))
    data = with_value(zeroshot)
    for ax, game in zip(axes, games):
        part = data[data["game"] == game]
        summary = summarise(part, ["population", "label"], "value").rename(columns={"population": "group"})
        _grouped_bars(ax, summary, sorted(summary["group"].unique()), paper, "paper")
        ax.set_ylabel("zero-shot return")
        ax.set_title(game, fontsize=10)
    _legend_below(fig, axes)
    return fig


def _heatmap(ax: plt.Axes, values: np.ndarray, rows: Sequence[str], cols: Sequence[str], fig: Figure, label: str) -> None:
    # Scores are non-negative: anchor the colour scale at 0 so that a uniform matrix is not stretched.
    low = 0.0 if np.isfinite(values).any() and np.nanmin(values) >= 0 else None
    image = ax.imshow(np.ma.masked_invalid(values), cmap="viridis", aspect="auto", vmin=low)
    ax.set_xticks(range(len(cols)), cols, rotation=90, fontsize=7)
    ax.set_yticks(range(len(rows)), rows, fontsize=7)
    if values.size <= 400 and np.isfinite(values).any():
        mid = (np.nanmin(values) + np.nanmax(values)) / 2
        for i in range(values.shape[0]):
            for j in range(values.shape[1]):
                if np.isfinite(values[i, j]):
                    # dark text on viridis' light (high) end, light text on its dark end
                    ax.text(j, i, f"{values[i, j]:.2g}", ha="center", va="center", fontsize=6, color="black" if values[i, j] > mid else "white")
    fig.colorbar(image, ax=ax, label=label)


def crossplay_heatmap(matrix: pd.DataFrame, title: str | None = None) -> Figure:
    """Cross-play score matrix as a heatmap: rows = ego-seat members of population A, columns = partners from B.

    `matrix` is a frame from `loaders.load_crossplay` (or `rllib_conv.pipelines.crossplay.crossplay`).
    With A = B the diagonal is self-play. Returns the Figure.
    """
    n_rows, n_cols = matrix.shape
    fig, ax = plt.subplots(figsize=(max(4.0, 0.45 * n_cols + 2.5), max(3.5, 0.4 * n_rows + 2.0)))
    _heatmap(ax, matrix.to_numpy(dtype=float), [str(i) for i in matrix.index], [str(c) for c in matrix.columns], fig, "mean score")
    ax.set_xlabel(matrix.columns.name or "partner (population B)")
    ax.set_ylabel(matrix.index.name or "ego seat (population A)")
    diagonal = list(matrix.index) == list(matrix.columns)
    ax.set_title(title or ("cross-play (diagonal: self-play)" if diagonal else "cross-play"), fontsize=10)
    fig.tight_layout()
    return fig


def selfplay_heatmap(reports: pd.DataFrame) -> Figure:
    """Self-play gate scores as a heatmap: one row per population, one column per partner; pairs that failed the gate get a red frame.

    `reports` is `loaders.load_selfplay_reports`'s frame. Returns the Figure.
    """
    table = reports.pivot_table(index="population", columns="partner", values="score", aggfunc="first")
    passed = reports.assign(passed=reports["passed"].astype(float)).pivot_table(index="population", columns="partner", values="passed", aggfunc="first")
    fig, ax = plt.subplots(figsize=(max(4.0, 0.35 * table.shape[1] + 2.5), max(2.2, 0.45 * table.shape[0] + 1.6)))
    _heatmap(ax, table.to_numpy(dtype=float), list(table.index), list(table.columns), fig, "self-play score")
    for i, population in enumerate(table.index):
        for j, partner in enumerate(table.columns):
            ok = passed.loc[population, partner] if partner in passed.columns else np.nan
            if pd.notna(ok) and not bool(ok):
                ax.add_patch(plt.Rectangle((j - 0.5, i - 0.5), 1, 1, fill=False, edgecolor="red", lw=1.5))
    ax.set_xlabel("partner")
    ax.set_title("self-play pairs: score at the gate (red frame: failed)", fontsize=10)
    fig.tight_layout()
    return fig


def user_study_bars(scores: pd.DataFrame, paper: Mapping[tuple[str, str], float] | None = None, title: str | None = None) -> Figure:
    """First-try coordination per context, Train (grey) vs Test (orange), with standard-error bars (the paper's fig:userstudy).

    `scores` is `summaries.user_study_scores`'s frame (task, context, score, sem);
    `paper` maps (task, context) to the paper figure's value, drawn as black crosses.
    Returns the Figure.
    """
    contexts = sorted(scores["context"].unique())
    fig, ax = plt.subplots(figsize=(5.0, 3.2))
    width = 0.38
    marked = False
    for k, task in enumerate(("train", "test")):
        part = scores[scores["task"] == task].set_index("context")
        xs = [i + (k - 0.5) * width for i, c in enumerate(contexts) if c in part.index]
        present = [c for c in contexts if c in part.index]
        if not present:
            continue
        sem = part.loc[present, "sem"].fillna(0.0).to_numpy()
        ax.bar(xs, part.loc[present, "score"], width=width * 0.95, yerr=sem, capsize=3, color=TASK_COLOURS[task], edgecolor="black", lw=0.5, label=task.capitalize())
        for x, c in zip(xs, present):
            if paper and (task, c) in paper:
                ax.plot([x], [paper[(task, c)]], marker="x", color="black", ms=7, mew=2, ls="none", label="paper figure" if not marked else None)
                marked = True
    ax.set_xticks(range(len(contexts)), [f"context {c}" for c in contexts])
    ax.set_ylim(0, 1.15)
    ax.set_ylabel("score: 1st try")
    ax.set_title(title or "user study: first-try coordination", fontsize=10)
    ax.legend(fontsize=8, loc="upper left", ncol=3)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig
