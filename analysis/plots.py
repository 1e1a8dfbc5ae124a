"""`plot_folder`: the PNGs beside a command's results, for people who would rather look than read.

`rllib-conv train`, `sweep`, `adapt` and `zeroshot` call it on what they wrote, and
`rllib-conv plot FOLDER` redraws (overwrites) the figures. It recognises:

- a training experiment folder `<storage>/<name>/` (trial folders holding config.yaml and
  progress.csv), or one trial folder: `learning_curves.png`, the return with each training
  partner against env steps, one panel per trial;
- a sweep (an experiment whose trials differ in more than their seed): the same, plus
  `sweep.png`, heat maps of each trial's final `return_mean` (and
  `eval/marginal_distance/paper` where measured) over the swept values, averaged over seeds;
- an adaptation CSV (`<name>.csv` with a `steps` column): `<name>.png`, curves per method;
- a zero-shot CSV (`<name>.csv` without one): `<name>.png`, bars per test partner and method;
- a folder of such CSVs: each one's PNG.

Bands and error bars are seed-level 95% t-intervals, and the figures that have them say so under their legend.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from analysis import figures, loaders
from analysis.loaders import CONFIG_PREFIX
from rllib_conv.common.run_folders import trial_folders

LEARNING_CURVES = "learning_curves.png"
SWEEP = "sweep.png"
# The final metrics a sweep's heat maps show, when its trials logged them.
SWEEP_METRICS: tuple[str, ...] = ("return_mean", "eval/marginal_distance/paper")
# Config keys that never count as swept: the seed is replicated, not swept; the name is bookkeeping.
NOT_SWEPT: frozenset[str] = frozenset({"seed", "name"})
# Swept keys read first, as the heat map's rows (then columns); others follow in name order.
KEY_ORDER: tuple[str, ...] = ("population", "method", "lam", "model.z_dim")
# Columns that tell an adaptation CSV from a zero-shot one (both also have run, method, seed, partner, mean_return).
STAGE_COLUMNS = {"run", "method", "seed", "partner", "mean_return"}
EXPECTED = (
    "a training or sweep folder (trial folders holding config.yaml and progress.csv), "
    "an adaptation or zero-shot CSV, or a folder of them"
)


def plot_folder(path: str | Path) -> list[Path]:
    """Draw the figures of `path` (see the module's docstring) as PNGs beside its data; return their paths.

    ValueError naming `path` when it is none of the things recognised.
    """
    path = Path(path)
    if path.is_file():
        return [_plot_csv(path)]
    if not path.is_dir():
        raise ValueError(f"{str(path)!r} does not exist; expected {EXPECTED}")
    if _holds_trained_egos(path):
        return _plot_training(path)
    csvs = [p for p in sorted(path.glob("*.csv")) if _stage_of(p)]
    if not csvs:
        raise ValueError(f"{str(path)!r} holds nothing to plot; expected {EXPECTED}")
    return [_plot_csv(p) for p in csvs]


def _holds_trained_egos(path: Path) -> bool:
    try:
        return bool(trial_folders(path))
    except ValueError:
        return False


def _stage_of(csv: Path) -> str | None:
    """'adaptation' or 'zeroshot' from a CSV's header, None for any other CSV and for one without rows (a stage that wrote nothing)."""
    try:
        head = pd.read_csv(csv, nrows=1)
    except pd.errors.EmptyDataError:
        return None
    if head.empty or not STAGE_COLUMNS <= set(head.columns):
        return None
    return "adaptation" if "steps" in head.columns else "zeroshot"


def _plot_csv(csv: Path) -> Path:
    """`<name>.png` beside an adaptation or zero-shot CSV."""
    stage = _stage_of(csv) if csv.suffix == ".csv" else None
    if stage is None:
        raise ValueError(
            f"{str(csv)!r} is not an adaptation or zero-shot CSV with rows (columns {sorted(STAGE_COLUMNS)}, plus steps for adaptation); expected {EXPECTED}"
        )
    table = loaders.read_stage_csv(csv)
    if stage == "adaptation":
        fig = figures.adaptation_curves(table, note=figures.band_caption(table, "Lines: mean over seeds; bands"))
    else:
        fig = figures.partner_bars(table, note=figures.band_caption(table, "Bars: mean over seeds; error bars", averaged=None))
    return figures.save_png(fig, csv.with_suffix(".png"))


def _plot_training(folder: Path) -> list[Path]:
    """`learning_curves.png` of a trial or experiment folder, and `sweep.png` when its trials sweep something."""
    trials = trial_folders(folder)
    curves = loaders.load_trial_curves(trials)
    if curves.empty:
        raise ValueError(f"{str(folder)!r} holds no training progress yet (progress.csv or result.json in its trial folders)")
    written = [figures.save_png(figures.partner_curves(curves), folder / LEARNING_CURVES)]
    summaries = loaders.load_trial_summaries(trials)
    tables = {m: sweep_table(summaries, m) for m in SWEEP_METRICS if m in summaries and summaries[m].notna().any()}
    tables = {m: t for m, t in tables.items() if not t.empty}
    if tables:
        written.append(figures.save_png(figures.sweep_heatmap(tables), folder / SWEEP))
    return written


def swept_keys(summaries: pd.DataFrame) -> list[str]:
    """The config keys (`lam`, `ppo.lr`, ...) whose values differ between the trials of `summaries`, seeds aside.

    `summaries` is `loaders.load_trial_summaries`'s frame. Ordered population, method, lam,
    z_dim first, then by name.
    """
    config = [c for c in summaries.columns if c.startswith(CONFIG_PREFIX) and c.removeprefix(CONFIG_PREFIX) not in NOT_SWEPT]
    varied = [c.removeprefix(CONFIG_PREFIX) for c in config if summaries[c].astype(str).nunique() > 1]
    return sorted(varied, key=lambda k: (KEY_ORDER.index(k) if k in KEY_ORDER else len(KEY_ORDER), k))


def sweep_table(summaries: pd.DataFrame, metric: str) -> pd.DataFrame:
    """The heat map of `metric`: the mean over seeds of each trial's final value, rows = the first swept key, columns = the others.

    `summaries` is `loaders.load_trial_summaries`'s frame. With one further swept key the
    columns are its values (`0.5`), with several their combinations (`lam=0.5, model.z_dim=8`),
    with none the metric's name; with no swept key at all (a plain training run) the table is empty.
    """
    keys = swept_keys(summaries)
    if not keys or metric not in summaries:
        return pd.DataFrame()
    data = summaries.dropna(subset=[metric]).rename(columns=lambda c: c.removeprefix(CONFIG_PREFIX))
    rows, cols = keys[0], keys[1:]
    # One further key: its values head the columns; several: their combinations, each value named.
    data["_column"] = (
        [
            str(v[0]) if len(cols) == 1 else ", ".join(f"{k}={x}" for k, x in zip(cols, v))
            for v in data[cols].itertuples(index=False)
        ]
        if cols
        else metric
    )
    table = data.pivot_table(index=rows, columns="_column", values=metric, aggfunc="mean")
    table.columns.name = ", ".join(cols)
    return table
