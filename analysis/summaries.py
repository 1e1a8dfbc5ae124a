"""Summary statistics shared by the figures and the report: seed-level means with 95% intervals, paired and
unpaired differences, adaptation AUC, user-study scores.

The unit that is replicated is the training seed: every curve or zero-shot row of one seed
comes from the same trained ego, so a seed's (seed, test partner) rows are not independent
and an interval over them would be too narrow. Every interval over results measured with
test partners is therefore computed in two stages: average each seed's rows over its test
partners, then take the two-sided 95% Student-t interval of the mean over the seed means
(n = seeds). With balanced partners this is the interval of the grand mean in the nested
(seed, partner) random-effects model. A (hierarchical) bootstrap is not used: with 3 to 5
seeds it resamples among at most 10 to 126 distinct seed sets, and its percentile intervals
are too narrow exactly where the seeds are few. With one seed there is no interval (NaN).

Methods of one population share seed numbers and test partners, so a comparison of two
methods is a paired difference: A's row (seed k, partner p) minus B's row (seed k, partner
p), averaged per seed, then the t-interval over seeds (`paired_difference`). Groups without
shared units (two populations) are compared by Welch's unpaired interval (`unpaired_difference`).

Populations above seeds. Where a result pools several independently trained populations of
one kind (a plan's self-play entry with `populations: N`; the frame then names the kind in
`population` and each row's own population in `POPULATION_ID`), the population is the
replicated unit: each seed's rows are averaged over its test partners, the seeds within a
population, and the t-interval is over the population means (n = populations). Paired
differences pair within (population, seed, partner) and are averaged up the same way. A group
with one population (every frame without `POPULATION_ID`) keeps the seed as its unit.
"""

from __future__ import annotations

import math
import warnings
from typing import Iterable, Sequence

import numpy as np
import pandas as pd
from scipy import stats

from rllib_conv.common.user_study_table import CONTEXTS, TASKS, first_try_scores

CONFIDENCE = 0.95
# The replicated unit: one trained ego per seed.
SEED = "seed"
# Where populations are pooled (see the module's docstring): the independently trained population a row came from.
POPULATION_ID = "population_id"
# The unit column of `unit_means`: a seed, or a population id where a group pools several.
UNIT = "unit"
# Keys that identify one adaptation curve (one trained ego adapting to one test partner).
CURVE_KEYS = ["game", "population", "label", "run", "seed", "partner"]


def curve_keys(df: pd.DataFrame) -> list[str]:
    """`CURVE_KEYS`, with `POPULATION_ID` where `df` pools populations."""
    return [*CURVE_KEYS, POPULATION_ID] if POPULATION_ID in df.columns else list(CURVE_KEYS)


def mean_ci(values: Iterable[float]) -> tuple[float, float, float, int]:
    """Mean of the finite `values` (independent units), its 95% t-interval (lo, hi) and the count n; the interval is NaN when n < 2."""
    x = np.asarray([v for v in values if v is not None and np.isfinite(v)], dtype=float)
    n = len(x)
    if n == 0:
        return math.nan, math.nan, math.nan, 0
    mean = float(x.mean())
    if n < 2:
        return mean, math.nan, math.nan, n
    half = float(stats.t.ppf(0.5 + CONFIDENCE / 2, n - 1) * stats.sem(x))
    return mean, mean - half, mean + half, n


def summarise(df: pd.DataFrame, by: Sequence[str], value: str) -> pd.DataFrame:
    """Group `df` by `by` and return one row per group: the `by` columns, mean, lo, hi (95% CI) and n of `value`.

    Each row of `df` counts as one independent unit; `seed_summary` is the one for rows that share seeds.
    """
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


def seed_means(df: pd.DataFrame, by: Sequence[str], value: str) -> pd.DataFrame:
    """One row per (`by`, seed): the mean of `value` over that seed's rows (its test partners), in column `value`."""
    if df.empty:
        return pd.DataFrame(columns=[*by, SEED, value])
    return df.groupby([*by, SEED], sort=True, dropna=False)[value].mean().reset_index()


def unit_means(df: pd.DataFrame, by: Sequence[str], value: str) -> pd.DataFrame:
    """One row per (`by`, unit): the mean of `value` over the unit's rows, in column `value`; the unit in column `UNIT`.

    The unit is the seed (its mean over its rows, e.g. test partners), or, in a group of `by`
    that pools several populations (`POPULATION_ID`), the population: its seeds' means
    averaged. Without `POPULATION_ID` this is `seed_means` with the seed column named `UNIT`.
    """
    by = list(by)
    if POPULATION_ID not in df.columns:
        return seed_means(df, by, value).rename(columns={SEED: UNIT})
    if df.empty:
        return pd.DataFrame(columns=[*by, UNIT, value])
    per_seed = df.groupby([*by, POPULATION_ID, SEED], sort=True, dropna=False)[value].mean().reset_index()
    if by:
        pooled = per_seed.groupby(by, sort=False, dropna=False)[POPULATION_ID].transform("nunique") > 1
    else:
        pooled = pd.Series(per_seed[POPULATION_ID].nunique() > 1, index=per_seed.index)
    populations = per_seed[pooled].groupby([*by, POPULATION_ID], sort=True, dropna=False)[value].mean().reset_index()
    seeds = per_seed[~pooled].drop(columns=POPULATION_ID)
    parts = [populations.rename(columns={POPULATION_ID: UNIT}), seeds.rename(columns={SEED: UNIT})]
    return pd.concat([x for x in parts if not x.empty] or parts[:1], ignore_index=True)[[*by, UNIT, value]]


def seed_summary(df: pd.DataFrame, by: Sequence[str], value: str) -> pd.DataFrame:
    """`summarise` with the seed as the unit: per group, each seed's mean over its rows, then the 95% t-interval over seeds (n = seeds).

    A group that pools several populations (`POPULATION_ID`) has the population as its unit
    (`unit_means`): seeds averaged within each population, the interval over populations (n = populations).
    """
    return summarise(unit_means(df, by, value), by, value)


def paired_difference(
    df: pd.DataFrame, a: str, b: str, value: str, within: Sequence[str] = ("partner",), label: str = "label"
) -> tuple[float, float, float, int]:
    """Mean difference A - B of `value` over the units A and B share, its 95% t-interval over seeds and the seed count.

    `df` holds the rows of one population; `label` tells A's rows (`a`) from B's (`b`).
    Rows are paired on (seed, *`within`), e.g. (seed k, partner p) of A with (seed k,
    partner p) of B; units only one of them has are left out. Each seed's differences are
    averaged, and the interval is over those seed means: NaN with fewer than two shared seeds.
    Where `df` pools several populations (`POPULATION_ID`), rows pair within (population,
    seed, *`within`), each seed's differences are averaged, then each population's seeds, and
    the interval and the count are over populations.
    """
    pooled = POPULATION_ID in df.columns and df[POPULATION_ID].nunique() > 1
    keys = [POPULATION_ID, SEED, *within] if pooled else [SEED, *within]
    sides = [df[df[label] == name].groupby(keys)[value].mean() for name in (a, b)]
    both = pd.concat(sides, axis=1, keys=["a", "b"], join="inner").dropna()
    if both.empty:
        return math.nan, math.nan, math.nan, 0
    if pooled:
        per_seed = (both["a"] - both["b"]).groupby(level=[POPULATION_ID, SEED]).mean()
        return mean_ci(per_seed.groupby(level=POPULATION_ID).mean())
    per_seed = (both["a"] - both["b"]).groupby(level=SEED).mean()
    return mean_ci(per_seed)


def seeds_for_half_width(sd: float, half_width: float) -> int:
    """The fewest units n (>= 2) whose 95% t-interval of a mean, at standard deviation `sd`, is narrower than +/- `half_width`.

    Half-width t(0.975, n - 1) * sd / sqrt(n): the power note's rule for declaring seeds before a run.
    """
    if not (sd >= 0 and half_width > 0):
        raise ValueError(f"need sd >= 0 and half_width > 0; got {sd}, {half_width}")
    n = 2
    while float(stats.t.ppf(0.5 + CONFIDENCE / 2, n - 1)) * sd / math.sqrt(n) >= half_width:
        n += 1
    return n


def unpaired_difference(a: Iterable[float], b: Iterable[float]) -> tuple[float, float, float, int]:
    """Difference of the means of two independent samples (seed means of two populations), Welch's 95% interval, and the smaller sample size.

    The interval is NaN unless both samples have two or more units.
    """
    x, y = (np.asarray([v for v in s if np.isfinite(v)], dtype=float) for s in (a, b))
    n = min(len(x), len(y))
    if n == 0:
        return math.nan, math.nan, math.nan, 0
    mean = float(x.mean() - y.mean())
    if n < 2:
        return mean, math.nan, math.nan, n
    with warnings.catch_warnings():
        # Identical seeds (zero variance) are a valid case with a zero-width interval; SciPy warns about its precision.
        warnings.simplefilter("ignore", RuntimeWarning)
        ci = stats.ttest_ind(x, y, equal_var=False).confidence_interval(CONFIDENCE)
    return mean, float(ci.low), float(ci.high), n


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
    """One row per adaptation curve (game, population, label, run, seed, partner; `POPULATION_ID` where pooled): `auc`, `start`, `end`, `points`.

    `curves` is `loaders.load_adaptation`'s frame. `auc` is the mean return over all the
    curve's evaluation points (step 0 included), i.e. the area under the curve divided by
    its length; `start` and `end` are the returns at the first and last step.
    """
    keys = curve_keys(curves)
    columns = [*keys, "auc", "start", "end", "points", "last_step", "value_source"]
    if curves.empty:
        return pd.DataFrame(columns=columns)
    data = with_value(curves).sort_values("steps")
    rows = []
    for key, g in data.groupby(keys, sort=True, dropna=False):
        rows.append(
            (
                *key,
                float(g["value"].mean()),
                float(g["value"].iloc[0]),
                float(g["value"].iloc[-1]),
                len(g),
                int(g["steps"].iloc[-1]),
                g["value_source"].iloc[0],
            )
        )
    return pd.DataFrame(rows, columns=columns)


def uniform_prior_return(num_contexts: int, symmetric: int, episodes: int) -> float:
    """Expected return, after `episodes` one-step episodes with a new bandit partner, of the uniform-prior adapter.

    That adapter is Bayes-optimal only under a uniform prior: each symmetric context's partner arm
    equally likely and independent of the other contexts. It is a reference, not an upper bound:
    an adapter whose prior is the training population (the convention posterior) beats it where
    test partners follow the training partners' conventions more often than chance (Arms 3
    self-play: 0.9783 against 0.9763). The bound is the full-information return, 1.

    It knows the true marginals, so it plays the one good arm of a rule context (return 1)
    and, on a symmetric context (two good arms) not yet seen, one of the two at random
    (return 1/2); having seen the context once it knows the partner's arm (a hit confirms it,
    a miss rules it out) and plays it. Contexts are uniform, so a given one is still unseen
    with probability (1 - 1/C)^t, and the return is (C - m)/C + m/C * (1 - (1 - 1/C)^t / 2).
    """
    if not 0 <= symmetric <= num_contexts or num_contexts < 1 or episodes < 0:
        raise ValueError(
            f"need 0 <= symmetric <= num_contexts, num_contexts >= 1, episodes >= 0; got {symmetric}, {num_contexts}, {episodes}"
        )
    unseen = (1.0 - 1.0 / num_contexts) ** episodes
    return (num_contexts - symmetric) / num_contexts + symmetric / num_contexts * (1.0 - unseen / 2.0)


def curve_band(curves: pd.DataFrame) -> pd.DataFrame:
    """Per (game, population, label, evaluation point): mean return with its seed-level 95% interval (the bands of the adaptation figures).

    At each point every seed's curves are averaged over its test partners first, and the
    interval is over those seed means (n = seeds). Points are matched by their order
    within each curve, not by step count: on multi-step games an update waits for
    episodes to end, so the k-th evaluation of one curve lands a few env steps away from
    another's (Hanabi: 1280, 1281, 1287). `steps` is the point's mean step count.
    """
    keys = ["game", "population", "label", "point"]
    columns = [*keys[:3], "steps", "mean", "lo", "hi", "n"]
    if curves.empty:
        return pd.DataFrame(columns=columns)
    data = with_value(curves).sort_values("steps")
    data["point"] = data.groupby(curve_keys(data), sort=False, dropna=False).cumcount()
    band = seed_summary(data, keys, "value")
    steps = data.groupby(keys, dropna=False)["steps"].mean().round().astype("int64").rename("steps").reset_index()
    return band.merge(steps, on=keys)[columns]


# --- user study --------------------------------------------------------------------------


def user_study_scores(
    study: pd.DataFrame, exclude_pairs: Iterable[int] = (), ddof: int = 1, swap_a: bool = False
) -> pd.DataFrame:
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
        out = out.iloc[sorted(range(len(out)), key=lambda i: rank[(out.at[i, "task"], out.at[i, "context"])])].reset_index(
            drop=True
        )
    return out


# The options under which the appendix table gives exactly the paper's bar chart (see analysis.paper.USER_STUDY_FIGURE_RECIPE).
PAPER_FIGURE_OPTIONS = {"exclude_pairs": (10,), "ddof": 0, "swap_a": True}


def paper_figure_recipe(study: pd.DataFrame) -> pd.DataFrame:
    """`user_study_scores` with the options that reproduce the paper's `fig:userstudy` from its appendix table."""
    return user_study_scores(study, **PAPER_FIGURE_OPTIONS)


def first_try_difference(
    study: pd.DataFrame, a: tuple[str, str], b: tuple[str, str], pair: str = "pair_id"
) -> tuple[float, float, float, int]:
    """Paired difference of first-try coordination between the (task, context) cells `a` and `b`: mean, 95% t-interval, pairs.

    `study` is a frame from `loaders.load_user_study_csvs`. Every pair plays every cell, so
    each pair gives one difference (1, 0 or -1: coordinated on its first try in `a` but not
    in `b`, ...); the interval is over the pairs that played both cells, the study's replicated unit.
    """
    first = study[study["try"] == 1].set_index(["task", "context", pair])["coordinated"].astype(float).sort_index()
    both = pd.concat([first.loc[a], first.loc[b]], axis=1, keys=["a", "b"], join="inner")
    return mean_ci(both["a"] - both["b"])
