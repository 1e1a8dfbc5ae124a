"""Summary statistics shared by the figures and the report: means with 95% intervals, adaptation AUC, user-study scores.

Intervals are two-sided 95% Student-t intervals of a mean over independent units
(seeds, or seed x test-partner curves); with one unit there is no interval (NaN).
The t quantiles are computed here (table up to 30 degrees of freedom, Cornish-Fisher
expansion above), so the package needs nothing beyond numpy and pandas.
"""

from __future__ import annotations

import math
from typing import Iterable, Sequence

import numpy as np
import pandas as pd

from rllib_conv.common.user_study_table import CONTEXTS, TASKS, first_try_scores

# Two-sided 95% quantiles t_{0.975, df} for df = 1..30 (standard tables).
_T975 = (
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
    2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
)  # fmt: skip
_Z975 = 1.959963984540054

# Keys that identify one adaptation curve (one trained ego adapting to one test partner).
CURVE_KEYS = ["game", "population", "label", "run", "seed", "partner"]


def t975(df: int) -> float:
    """The 0.975 quantile of Student's t with `df` degrees of freedom (NaN for df < 1)."""
    if df < 1:
        return math.nan
    if df <= len(_T975):
        return _T975[df - 1]
    # Cornish-Fisher expansion around the normal quantile: error < 1e-4 for df > 30.
    z = _Z975
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


def mean_ci(values: Iterable[float]) -> tuple[float, float, float, int]:
    """Mean of the finite `values`, its 95% t-interval (lo, hi) and the count n; the interval is NaN when n < 2."""
    x = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    n = len(x)
    if n == 0:
        return math.nan, math.nan, math.nan, 0
    mean = float(x.mean())
    if n < 2:
        return mean, math.nan, math.nan, n
    half = t975(n - 1) * float(x.std(ddof=1)) / math.sqrt(n)
    return mean, mean - half, mean + half, n


def summarise(df: pd.DataFrame, by: Sequence[str], value: str) -> pd.DataFrame:
    """Group `df` by `by` and return one row per group: the `by` columns, mean, lo, hi (95% CI) and n of `value`."""
    columns = [*by, "mean", "lo", "hi", "n"]
    if df.empty:
        return pd.DataFrame(columns=columns)
    rows = []
    for key, group in df.groupby(list(by), sort=True, dropna=False):
        key = key if isinstance(key, tuple) else (key,)
        rows.append((*key, *mean_ci(group[value])))
    out = pd.DataFrame(rows, columns=columns)
    out["n"] = out["n"].astype("int64")
    return out


def value_column(df: pd.DataFrame) -> str:
    """The return column to summarise: `exact_return` when every row has one (the bandit's exact expectation), else `mean_return`.

    The exact expected return measures the same thing as the 200-episode mean without its
    sampling noise, so it is preferred wherever the pipeline could compute it.
    """
    if "exact_return" in df.columns and len(df) and df["exact_return"].notna().all():
        return "exact_return"
    return "mean_return"


def with_value(df: pd.DataFrame) -> pd.DataFrame:
    """A copy of a curve or zero-shot frame with a `value` column, chosen per population by `value_column`."""
    out = df.copy()
    out["value"] = np.nan
    out["value_source"] = ""
    if out.empty:
        return out
    for _, index in out.groupby(["game", "population"]).groups.items():
        part = out.loc[index]
        column = value_column(part)
        out.loc[index, "value"] = part[column].astype(float)
        out.loc[index, "value_source"] = column
    return out


def adaptation_auc(curves: pd.DataFrame) -> pd.DataFrame:
    """One row per adaptation curve (game, population, label, run, seed, partner): `auc`, `start`, `end`, `points`.

    `curves` is `loaders.load_adaptation`'s frame. `auc` is the mean return over all the
    curve's evaluation points (step 0 included), i.e. the area under the curve divided by
    its length; `start` and `end` are the returns at the first and last step.
    """
    columns = [*CURVE_KEYS, "auc", "start", "end", "points", "last_step", "value_source"]
    if curves.empty:
        return pd.DataFrame(columns=columns)
    data = with_value(curves).sort_values("steps")
    rows = []
    for key, g in data.groupby(CURVE_KEYS, sort=True, dropna=False):
        rows.append(
            (*key, float(g["value"].mean()), float(g["value"].iloc[0]), float(g["value"].iloc[-1]), len(g), int(g["steps"].iloc[-1]), g["value_source"].iloc[0])
        )
    return pd.DataFrame(rows, columns=columns)


def bayes_optimal_return(num_contexts: int, symmetric: int, episodes: int) -> float:
    """Expected return, after `episodes` one-step episodes with a new bandit partner, of the Bayes-optimal adapter.

    It knows the true marginals, so it plays the one good arm of a rule context (return 1)
    and, on a symmetric context (two good arms) not yet seen, one of the two at random
    (return 1/2); having seen the context once it knows the partner's arm (a hit confirms it,
    a miss rules it out) and plays it. Contexts are uniform, so a given one is still unseen
    with probability (1 - 1/C)^t, and the return is (C - m)/C + m/C * (1 - (1 - 1/C)^t / 2).
    """
    if not 0 <= symmetric <= num_contexts or num_contexts < 1 or episodes < 0:
        raise ValueError(f"need 0 <= symmetric <= num_contexts, num_contexts >= 1, episodes >= 0; got {symmetric}, {num_contexts}, {episodes}")
    unseen = (1.0 - 1.0 / num_contexts) ** episodes
    return (num_contexts - symmetric) / num_contexts + symmetric / num_contexts * (1.0 - unseen / 2.0)


def curve_band(curves: pd.DataFrame) -> pd.DataFrame:
    """Per (game, population, label, evaluation point): mean return over curves with its 95% interval (the bands of the adaptation figures).

    Points are matched by their order within each curve, not by step count: on multi-step
    games an update waits for episodes to end, so the k-th evaluation of one curve lands a
    few env steps away from another's (Hanabi: 1280, 1281, 1287). `steps` is the point's
    mean step count.
    """
    keys = ["game", "population", "label", "point"]
    columns = [*keys[:3], "steps", "mean", "lo", "hi", "n"]
    if curves.empty:
        return pd.DataFrame(columns=columns)
    data = with_value(curves).sort_values("steps")
    data["point"] = data.groupby(CURVE_KEYS, sort=False, dropna=False).cumcount()
    band = summarise(data, keys, "value")
    steps = data.groupby(keys, dropna=False)["steps"].mean().round().astype("int64").rename("steps").reset_index()
    return band.merge(steps, on=keys)[columns]


# --- user study --------------------------------------------------------------------------


def user_study_scores(study: pd.DataFrame, exclude_pairs: Iterable[int] = (), ddof: int = 1, swap_a: bool = False) -> pd.DataFrame:
    """First-try coordination per (task, context): score, standard error, n and the count of coordinated pairs.

    `study` is a frame from `loaders.load_user_study_csvs` (or `load_user_study`). The score
    of a bar is the share of pairs whose first try was coordinated (same good arm);
    `sem` = std(ddof) / sqrt(n). `exclude_pairs` drops those pair IDs first; `swap_a`
    exchanges the Train-A and Test-A bars. The defaults compute the numbers straight from
    the table; `paper_figure_recipe` gives the options that reproduce the paper's figure.
    Rows come ordered train A, B, C then test A, B, C.
    """
    out = first_try_scores(study, exclude_pairs, ddof)
    if swap_a:
        a = out["context"] == "A"
        out.loc[a, "task"] = out.loc[a, "task"].map({"train": "test", "test": "train"})
        rank = {key: i for i, key in enumerate((t, c) for t in TASKS for c in CONTEXTS)}
        out = out.iloc[sorted(range(len(out)), key=lambda i: rank[(out.at[i, "task"], out.at[i, "context"])])].reset_index(drop=True)
    return out


# The options under which the appendix table gives exactly the paper's bar chart (see analysis.paper.USER_STUDY_FIGURE_RECIPE).
PAPER_FIGURE_OPTIONS = {"exclude_pairs": (10,), "ddof": 0, "swap_a": True}


def paper_figure_recipe(study: pd.DataFrame) -> pd.DataFrame:
    """`user_study_scores` with the options that reproduce the paper's `fig:userstudy` from its appendix table."""
    return user_study_scores(study, **PAPER_FIGURE_OPTIONS)
