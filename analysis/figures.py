"""The report's figures: each function takes a tidy DataFrame (from `analysis.loaders`) and returns a matplotlib Figure.

Nothing here reads files or shows windows; `save` writes a figure as PNG and PDF.
Lines and bars are means over seeds, each seed averaged over its test partners first; bands
and error bars are the seed-level 95% t-intervals of `analysis.summaries` (no band for a
method with one seed); `band_caption` says so with the n, for the report's caption under a
figure or the `note` a figure function prints under its legend.
Colours are colour-blind safe (Okabe & Ito's palette, then Tol's muted one) and each method
has its own colour and line style; the paper's method (ours λ=0.5) is drawn on top, thicker.
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
from analysis.summaries import curve_band, seed_summary, with_value  # noqa: E402
from rllib_conv.common.methods import (  # noqa: E402
    BC_TRAINED,
    BEYOND_GUARDED,
    BEYOND_PLASTIC,
    BEYOND_POSTERIOR,
    CONTROL_COUNTS,
    CONTROL_LOOKUP,
    CONTROL_PRIOR,
    GUARDED,
    HEAD_PENALTY,
    HEAD_PENALTY_PICKED,
    LAM0,
    LAM03,
    LOW_Z,
    PAPER_METHOD,
    PICKED,
    PPO_BC,
    SCRATCH,
    SEAT_HEADS,
    SEAT_KNOWN,
)
from rllib_conv.common.methods import LABELS as LABEL_ORDER  # noqa: E402  (methods in the order of the paper's legends)

# (colour, line style) per method: no two colours alike, and every method but the paper's and the
# baselines with a dash pattern of its own. The paper's method, the baselines, the oracle and
# scratch take the Okabe-Ito colours (colour-blind safe: Okabe & Ito 2008), ours' variants Tol's muted ones.
LABEL_STYLES: dict[str, tuple[str, str | tuple]] = {
    PAPER_METHOD: ("#D55E00", "-"),  # vermillion: the paper's method
    "agg": ("#0072B2", "-"),  # blue
    "no_task_logits": ("#56B4E9", "-."),  # sky blue
    "maml": ("#CC79A7", "-"),  # reddish purple
    "oracle": ("#009E73", "-"),  # bluish green (the paper's "green oracle curve")
    PPO_BC: ("#F0E442", (0, (3, 1, 1, 1, 1, 1, 1, 1))),  # yellow, dash-dot-dot-dot: Carroll et al.'s PPO_BC (Overcooked)
    SCRATCH: ("#000000", ":"),
    LAM0: ("#E69F00", "--"),  # orange
    LAM03: ("#882255", (0, (3, 1, 1, 1))),  # wine, dash-dot
    LOW_Z: ("#332288", (0, (6, 1.5))),  # indigo, long dashes (dots read as from scratch's black)
    HEAD_PENALTY: ("#44AA99", (0, (5, 1, 1, 1, 1, 1))),  # teal, dash-dot-dot (not in the paper)
    SEAT_HEADS: ("#EE3377", (0, (1, 2, 4, 2))),  # Tol's vibrant magenta, dot-dash: a head per seat and partner (k seats)
    SEAT_KNOWN: ("#009988", (0, (4, 1, 1, 1, 1, 1, 1, 1))),  # Tol's vibrant teal: the same egos, known members' heads kept
    PICKED: ("#999933", (0, (8, 2))),  # olive, long dashes (not in the paper)
    HEAD_PENALTY_PICKED: ("#888888", (0, (8, 2, 1, 2))),  # grey, long dash-dot (not in the paper)
    GUARDED: ("#AA4499", (0, (2, 2))),  # purple, short dashes: ours, its fine-tuning guarded (not in the paper)
    BC_TRAINED: ("#88CCEE", (0, (5, 2, 1, 2))),  # cyan, dash-dot: ours trained with the BC proxies (not in the paper)
    BEYOND_POSTERIOR: ("#661100", "-"),  # dark brown, solid: the adapter beyond the paper
    BEYOND_GUARDED: ("#CC6677", (0, (4, 2))),  # rose, dashes: the same adapter, its fine-tuning guarded
    BEYOND_PLASTIC: ("#EE7733", (0, (2, 1, 2, 4))),  # Tol's vibrant orange, paired dashes: PLASTIC-Policy (k seats)
    # The posterior's information-parity controls: colours and dashes of their own.
    CONTROL_LOOKUP: ("#5D3A9B", (0, (1, 1))),  # deep violet, dense dots
    CONTROL_COUNTS: ("#DDAA33", (0, (10, 2, 2, 2, 2, 2))),  # gold, very long dash, two dots
    CONTROL_PRIOR: ("#004488", (0, (6, 2, 2, 2))),  # dark blue, long dash-short dash
}
OTHER_STYLE: tuple[str, str | tuple] = ("#117733", (0, (1, 3)))  # any label not listed: Tol's green, sparse dots
TASK_COLOURS = {"train": "0.8", "test": "#E69F00"}  # the paper's grey and orange bars (orange: Okabe-Ito)


def ordered_labels(labels: Sequence[str]) -> list[str]:
    """`labels` (unique) in the paper's legend order, unknown ones last in name order."""
    known = [x for x in LABEL_ORDER if x in set(labels)]
    return known + sorted(set(labels) - set(LABEL_ORDER))


def style(label: str) -> tuple[str, str | tuple]:
    """The (colour, line style) of a method label."""
    return LABEL_STYLES.get(label, OTHER_STYLE)


def colour(label: str) -> str:
    """The plotting colour of a method label."""
    return style(label)[0]


def band_caption(frame: pd.DataFrame, what: str = "Bands", averaged: str | None = "its test partners") -> str:
    """What a figure's bands or error bars are, with their n: `<what>: seed-level 95% t-interval ..., n = 3 seeds per method`.

    `frame` is the figure's data (one row per seed, partner, ...); n counts the seeds of each
    (population, label) it holds, as a range when they differ. `averaged` names what each
    seed is averaged over first (None: nothing, one value per seed).
    """
    keys = [k for k in ("population", "label") if k in frame.columns]
    if frame.empty or "seed" not in frame.columns:
        return f"{what}: seed-level 95% t-interval (no data)."
    counts = frame.groupby(keys)["seed"].nunique() if keys else pd.Series([frame["seed"].nunique()])
    low, high = int(counts.min()), int(counts.max())
    n = f"{low} seed" if low == high == 1 else f"{low} seeds" if low == high else f"{low}–{high} seeds"
    first = f" (each seed averaged over {averaged} first)" if averaged else ""
    none = "; no band where n = 1" if low == 1 else ""
    return f"{what}: 95% t-interval over seeds{first}, n = {n} per method{none}."


def save(fig: Figure, path_stem: str | Path, dpi: int = 130) -> tuple[Path, Path]:
    """Write `fig` as `<path_stem>.png` and `<path_stem>.pdf` (folders created), close it, and return both paths."""
    stem = Path(path_stem)
    pdf = stem.with_name(stem.name + ".pdf")
    stem.parent.mkdir(parents=True, exist_ok=True)
    # No creation date: a rebuilt report leaves unchanged figures byte-identical (no git churn).
    fig.savefig(pdf, bbox_inches="tight", metadata={"CreationDate": None})
    return save_png(fig, stem.with_name(stem.name + ".png"), dpi), pdf


def save_png(fig: Figure, png: str | Path, dpi: int = 130) -> Path:
    """Write `fig` as the one PNG `png` (folders created, the file overwritten), close it, and return the path."""
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return png


def _grid(n: int, ncols: int, size: tuple[float, float] = (4.0, 3.0)) -> tuple[Figure, list[plt.Axes]]:
    ncols = max(1, min(ncols, n))
    nrows = max(1, -(-n // ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(size[0] * ncols, size[1] * nrows), squeeze=False)
    flat = list(axes.ravel())
    for ax in flat[n:]:
        ax.set_visible(False)
    return fig, flat[:n]


def _legend_below(fig: Figure, axes: Sequence[plt.Axes], note: str = "") -> None:
    """One legend for all `axes`, below them and no wider than the figure (fewer columns until it fits), and `note` under it."""
    handles: dict[str, object] = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    fig.tight_layout()
    bottom = 0.0
    renderer = fig.canvas.get_renderer()
    if handles:
        # Below the figure, whatever its rows: `save` crops to the drawn content, legend included.
        for ncol in range(min(5, len(handles)), 0, -1):
            legend = fig.legend(
                list(handles.values()),
                list(handles),
                loc="upper center",
                ncol=ncol,
                frameon=False,
                bbox_to_anchor=(0.5, 0.0),
                fontsize=8,
            )
            box = legend.get_window_extent(renderer)
            if box.width <= fig.bbox.width or ncol == 1:
                break
            legend.remove()
        bottom = box.y0 / fig.bbox.height
    if note:
        fig.text(0.5, bottom - 0.01, note, ha="center", va="top", fontsize=7, wrap=True)


def _band_plot(ax: plt.Axes, band: pd.DataFrame, x: str) -> None:
    """One line per label with its 95% band (`band` has columns label, x, mean, lo, hi); the paper's method on top, thicker."""
    for label in ordered_labels(band["label"].unique()):
        part = band[band["label"] == label].sort_values(x)
        ours = label == PAPER_METHOD
        colour_, dashes = style(label)
        ax.plot(
            part[x],
            part["mean"],
            linestyle=dashes,
            color=colour_,
            label=label_name(label),
            lw=2.6 if ours else 1.5,
            zorder=4 if ours else 3,
        )
        has_ci = part["lo"].notna()
        if has_ci.any():
            ax.fill_between(
                part.loc[has_ci, x],
                part.loc[has_ci, "lo"],
                part.loc[has_ci, "hi"],
                color=colour_,
                alpha=0.25 if ours else 0.12,
                lw=0,
                zorder=2,
            )


def adaptation_curves(
    curves: pd.DataFrame,
    panels: Sequence[str] | None = None,
    titles: Mapping[str, str] | None = None,
    ncols: int = 4,
    title: str | None = None,
    note: str = "",
) -> Figure:
    """Adaptation to a new partner (the paper's fig:armsexp / fig:armsexpselfplay / fig:blockshanabiexp).

    `curves` is `loaders.load_adaptation`'s frame. One panel per population (`panels`
    picks and orders them; default all, by name), one line per method label: mean return
    over seeds (each seed averaged over its test partners) at each adaptation step, with
    its seed-level 95% band (`summaries.curve_band`); `note` is printed under the legend.
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
    _legend_below(fig, axes, note)
    return fig


def training_curves(
    training: pd.DataFrame, metric: str = "return_mean", panels: Sequence[str] | None = None, ncols: int = 4
) -> Figure:
    """Training return against env steps: one panel per population, one line per label, 95% band over seeds.

    `training` is `loaders.load_training`'s frame; `metric` one of its columns. Seeds
    are aligned on `training_iteration`, their steps averaged. Returns the Figure.
    """
    populations = list(panels) if panels is not None else sorted(training["population"].unique())
    fig, axes = _grid(max(1, len(populations)), ncols)
    if not training.empty and metric in training.columns:
        band = seed_summary(training.dropna(subset=[metric]), ["population", "label", "training_iteration"], metric)
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
    ax: plt.Axes,
    summary: pd.DataFrame,
    groups: Sequence[str],
    paper: Mapping[tuple[str, str], float] | None,
    paper_label: str,
    values: bool = False,
) -> None:
    """Bars of `summary` (group, label, mean, lo, hi) grouped by `groups`, one colour per label; paper values as black crosses.

    Each group shows only the labels it has, side by side and centred (no empty slot for a
    method that was not run); `values` prints each bar's mean above it.
    """
    labels = ordered_labels(summary["label"].unique())
    widest = max([summary[summary["group"] == g]["label"].nunique() for g in groups] or [1])
    width = 0.8 / max(1, widest)
    drawn: set[str] = set()
    marked = False
    for i, group in enumerate(groups):
        part = summary[summary["group"] == group].set_index("label")
        present = [lab for lab in labels if lab in part.index]
        for j, label in enumerate(present):
            r = part.loc[label]
            x = i + width * (j - (len(present) - 1) / 2)
            err = [[r["mean"] - r["lo"] if np.isfinite(r["lo"]) else 0.0], [r["hi"] - r["mean"] if np.isfinite(r["hi"]) else 0.0]]
            ax.bar(
                [x],
                [r["mean"]],
                width=width * 0.95,
                color=colour(label),
                label=label_name(label) if label not in drawn else None,
                yerr=err,
                capsize=2,
                edgecolor="black",
                lw=0.4,
            )
            drawn.add(label)
            if values:
                # Above the error bar, so that the two never overlap.
                top = r["hi"] if np.isfinite(r["hi"]) else r["mean"]
                ax.annotate(
                    f"{r['mean']:.3f}",
                    (x, top),
                    xytext=(0, 2),
                    textcoords="offset points",
                    ha="center",
                    va="bottom",
                    fontsize=6,
                    rotation=90,
                )
            if paper and (group, label) in paper:
                ax.plot(
                    [x],
                    [paper[(group, label)]],
                    marker="x",
                    color="black",
                    ms=7,
                    mew=2,
                    ls="none",
                    label=paper_label if not marked else None,
                )
                marked = True
    if values:
        ax.margins(y=0.18)  # room for the printed values
    ax.set_xticks(range(len(groups)), [population_name(g) for g in groups], fontsize=8)
    ax.grid(axis="y", alpha=0.3)


def marginal_bars(marginals: pd.DataFrame, paper: Mapping[tuple[str, str], float] | None = None) -> Figure:
    """Distance between each task module and the true marginals (the paper's fig:marginals).

    `marginals` is `loaders.load_marginals`'s frame: bars per population (groups) and
    method label, height = mean `distance` over seeds (printed on the bar) with 95% error
    bars; only the methods run in a population get a bar. `paper` maps (population, label)
    to the paper's value, drawn as black crosses. Returns the Figure.
    """
    fig, ax = plt.subplots(figsize=(max(5.0, 1.6 * max(1, marginals["population"].nunique()) + 3), 3.4))
    summary = seed_summary(marginals, ["population", "label"], "distance").rename(columns={"population": "group"})
    _grouped_bars(ax, summary, sorted(summary["group"].unique()), paper, "paper", values=True)
    ax.set_ylim(bottom=0.0)  # distances are non-negative; a t-interval reaching below 0 is cut there
    ax.set_ylabel("L1 distance to true marginals")
    ax.set_title("task module vs true marginals (lower is better)", fontsize=10)
    _legend_below(fig, [ax])
    return fig


def zeroshot_bars(zeroshot: pd.DataFrame, paper: Mapping[tuple[str, str], float] | None = None) -> Figure:
    """Zero-shot return on the new task with the test partners (the paper's fig:zeroshot).

    `zeroshot` is `loaders.load_zeroshot`'s frame. One panel per game (their score scales
    differ), bars per population and method label: mean over seeds (each averaged over its
    test partners) of the exact return where known, else the evaluated mean, with
    seed-level 95% error bars; `paper` values as black crosses. Returns the Figure.
    """
    games = sorted(zeroshot["game"].unique()) if not zeroshot.empty else ["(none)"]
    fig, axes = _grid(len(games), len(games), size=(5.0, 3.4))
    data = with_value(zeroshot)
    for ax, game in zip(axes, games):
        part = data[data["game"] == game]
        summary = seed_summary(part, ["population", "label"], "value").rename(columns={"population": "group"})
        _grouped_bars(ax, summary, sorted(summary["group"].unique()), paper, "paper")
        ax.set_ylabel("zero-shot return")
        ax.set_title(game, fontsize=10)
    _legend_below(fig, axes)
    return fig


def partner_curves(training: pd.DataFrame, ncols: int = 4) -> Figure:
    """Learning curves per training partner: one panel per trial, one line per `return/<partner>` column against env steps.

    `training` is `loaders.load_trial_curves`'s frame (one row per trial and iteration);
    `return_mean` is drawn thick and black. Partners are coloured along viridis (perceptually
    uniform, readable in grey and by colour-blind readers). Returns the Figure.
    """
    runs = sorted(training["run"].unique()) if not training.empty else []
    fig, axes = _grid(max(1, len(runs)), ncols)
    partners = sorted(c for c in training.columns if c.startswith("return/"))
    shades = matplotlib.colormaps["viridis"](np.linspace(0.0, 0.9, max(1, len(partners))))
    for ax, run in zip(axes, runs):
        part = training[training["run"] == run].sort_values("steps")
        for column, shade in zip(partners, shades):
            if part[column].notna().any():
                ax.plot(part["steps"], part[column], color=shade, lw=1.0, label=column.split("/", 1)[1])
        if "return_mean" in part:
            ax.plot(part["steps"], part["return_mean"], color="black", lw=2.2, label="mean over partners", zorder=4)
        first = part.iloc[0]
        lam = f" λ={first['lam']:g}" if pd.notna(first.get("lam")) else ""
        ax.set_title(f"{population_name(str(first['population']))} · {first['method']}{lam} · seed {first['seed']}", fontsize=9)
        ax.set_xlabel("training env steps")
        ax.set_ylabel("return")
        ax.grid(alpha=0.3)
    _legend_below(fig, axes)
    return fig


def sweep_heatmap(tables: Mapping[str, pd.DataFrame]) -> Figure:
    """One heat map per metric of a sweep: `tables` maps a metric's name to its table (rows and columns: swept values).

    The tables are `analysis.plots.sweep_table`'s (mean over seeds of each trial's final value).
    Returns the Figure.
    """
    fig, axes = _grid(
        max(1, len(tables)), len(tables) or 1, size=(max(4.0, 0.9 * max([t.shape[1] for t in tables.values()] or [1]) + 2.5), 3.4)
    )
    for ax, (metric, table) in zip(axes, tables.items()):
        _heatmap(
            ax,
            table.to_numpy(dtype=float),
            [str(i) for i in table.index],
            [str(c) for c in table.columns],
            fig,
            f"final {metric} (mean over seeds)",
        )
        ax.set_ylabel(table.index.name or "")
        ax.set_xlabel(table.columns.name or "")
        ax.set_title(metric, fontsize=10)
    fig.tight_layout()
    return fig


def partner_bars(zeroshot: pd.DataFrame, note: str = "") -> Figure:
    """Zero-shot return per test partner and method: one group of bars per partner, one colour per method.

    `zeroshot` is `loaders.read_stage_csv`'s frame of a zero-shot CSV. Each bar is the mean
    over seeds (exact return where known) with its 95% error bar over seeds; `note` is printed
    under the legend. Returns the Figure.
    """
    data = with_value(zeroshot)
    summary = seed_summary(data, ["partner", "label"], "value").rename(columns={"partner": "group"})
    groups = sorted(summary["group"].unique())
    fig, ax = plt.subplots(figsize=(max(5.0, 1.2 * len(groups) + 2.5), 3.4))
    _grouped_bars(ax, summary, groups, None, "")
    ax.set_xlabel("test partner")
    ax.set_ylabel("zero-shot return")
    _legend_below(fig, [ax], note)
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
                    ax.text(
                        j,
                        i,
                        f"{values[i, j]:.2g}",
                        ha="center",
                        va="center",
                        fontsize=6,
                        color="black" if values[i, j] > mid else "white",
                    )
    fig.colorbar(image, ax=ax, label=label)


def crossplay_heatmap(matrix: pd.DataFrame, title: str | None = None) -> Figure:
    """Cross-play score matrix as a heatmap: rows = ego-seat members of population A, columns = partners from B.

    `matrix` is a frame from `loaders.load_crossplay` (or `rllib_conv.pipelines.crossplay.crossplay`).
    With A = B the diagonal is self-play. Returns the Figure.
    """
    n_rows, n_cols = matrix.shape
    fig, ax = plt.subplots(figsize=(max(4.0, 0.45 * n_cols + 2.5), max(3.5, 0.4 * n_rows + 2.0)))
    _heatmap(
        ax, matrix.to_numpy(dtype=float), [str(i) for i in matrix.index], [str(c) for c in matrix.columns], fig, "mean score"
    )
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
    passed = reports.assign(passed=reports["passed"].astype(float)).pivot_table(
        index="population", columns="partner", values="passed", aggfunc="first"
    )
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


def user_study_bars(
    scores: pd.DataFrame, paper: Mapping[tuple[str, str], float] | None = None, title: str | None = None
) -> Figure:
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
        ax.bar(
            xs,
            part.loc[present, "score"],
            width=width * 0.95,
            yerr=sem,
            capsize=3,
            color=TASK_COLOURS[task],
            edgecolor="black",
            lw=0.5,
            label=task.capitalize(),
        )
        for x, c in zip(xs, present):
            if paper and (task, c) in paper:
                ax.plot(
                    [x],
                    [paper[(task, c)]],
                    marker="x",
                    color="black",
                    ms=7,
                    mew=2,
                    ls="none",
                    label="paper figure" if not marked else None,
                )
                marked = True
    ax.set_xticks(range(len(contexts)), [f"context {c}" for c in contexts])
    ax.set_ylim(0, 1.15)
    ax.set_ylabel("score: 1st try")
    ax.set_title(title or "user study: first-try coordination", fontsize=10)
    ax.legend(fontsize=8, loc="upper left", ncol=3)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    return fig
