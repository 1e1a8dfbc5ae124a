"""Aggregate scores the way the field reports them: mean and interquartile mean, with bootstrap intervals over seeds.

Agarwal et al. (NeurIPS 2021, `rliable`) and jax-aht report a method by the mean and the
IQM (the mean of the middle 50% of scores) of its normalised scores, each with a 95%
bootstrap interval in which the **seed** is the unit resampled: one seed's scores against
every partner stay together, since they share one trained network. Here with
`scipy.stats.bootstrap`, percentile intervals (BCa is undefined when every seed agrees,
and the interval is then that one value). No torch, no Ray: the analysis can read it too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import stats

IQM_CUT = 0.25  # cut a quarter from each end: the interquartile mean


def iqm(values: np.ndarray, axis: int = -1) -> np.ndarray:
    """The interquartile mean of `values` along `axis` (`scipy.stats.trim_mean`, 25% off each end, as `rliable`)."""
    return stats.trim_mean(values, IQM_CUT, axis=axis)


def mean(values: np.ndarray, axis: int = -1) -> np.ndarray:
    """The plain mean along `axis` (named beside `iqm`, so both are statistics of one signature)."""
    return np.mean(values, axis=axis)


Statistic = Callable[[np.ndarray, int], np.ndarray]  # (values, axis) -> the statistic along axis


@dataclass(frozen=True)
class Interval:
    """A statistic of all scores, and its bootstrap interval over seeds (NaN with fewer than 2 seeds)."""

    value: float
    low: float
    high: float


def over_seeds(
    scores: np.ndarray, statistic: Statistic, resamples: int = 9999, confidence: float = 0.95, seed: int = 0
) -> Interval:
    """`statistic` of every score of `scores` [seeds, partners], with its percentile bootstrap interval resampling seeds (rows).

    One seed gives no interval (NaN): resampling a single seed would show a spread of zero.
    """
    scores = np.asarray(scores, dtype=np.float64)
    if scores.ndim != 2 or scores.size == 0:
        raise ValueError(f"scores must be a non-empty [seeds, partners] table, got shape {scores.shape}")
    value = float(statistic(scores.reshape(-1), -1))
    if len(scores) < 2:
        return Interval(value, np.nan, np.nan)

    def resampled(rows: np.ndarray, axis: int = -1) -> np.ndarray:
        # rows [..., seeds]: seed indices; every partner's score of each picked seed enters the statistic.
        picked = scores[np.asarray(rows, dtype=np.int64)]
        return statistic(picked.reshape(*picked.shape[:-2], -1), -1)

    result = stats.bootstrap(
        (np.arange(len(scores)),),
        resampled,
        vectorized=True,
        n_resamples=resamples,
        confidence_level=confidence,
        method="percentile",
        rng=np.random.default_rng(seed),
    )
    return Interval(value, float(result.confidence_interval.low), float(result.confidence_interval.high))
