"""Mean and IQM with bootstrap intervals over seeds (`common.aggregates`): known answers and the interval's edge cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from rllib_conv.common.aggregates import iqm, mean, over_seeds


def test_the_iqm_is_the_mean_of_the_middle_half() -> None:
    assert iqm(np.arange(1.0, 9.0)) == pytest.approx(4.5)  # (3 + 4 + 5 + 6) / 4
    assert iqm(np.array([0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 100.0, -100.0])) == pytest.approx(0.75)  # the outliers cut
    assert iqm(np.full(7, 0.3)) == pytest.approx(0.3)


def test_the_statistic_pools_every_seed_and_partner() -> None:
    scores = np.array([[1.0, 0.5], [0.8, 0.9], [0.2, 0.4]])
    assert over_seeds(scores, mean).value == pytest.approx(scores.mean())
    assert over_seeds(scores, iqm).value == pytest.approx(iqm(scores.reshape(-1)))


def test_seeds_that_all_agree_give_a_degenerate_interval_and_one_seed_none() -> None:
    agree = over_seeds(np.tile([0.2, 0.6, 1.0], (5, 1)), mean)
    assert agree.value == pytest.approx(0.6) and agree.low == pytest.approx(0.6) and agree.high == pytest.approx(0.6)
    alone = over_seeds(np.array([[0.2, 0.6]]), mean)
    assert alone.value == pytest.approx(0.4) and np.isnan(alone.low) and np.isnan(alone.high)
    with pytest.raises(ValueError, match="non-empty"):
        over_seeds(np.zeros((0, 3)), mean)


def test_the_seed_is_the_unit_resampled() -> None:
    # Two seeds, each consistent across partners: every resample's mean is 0, 0.5 or 1, a seed's
    # partners never split up; resampling cells would give values in between.
    scores = np.array([[1.0, 1.0, 1.0], [0.0, 0.0, 0.0]])
    interval = over_seeds(scores, mean, resamples=999)
    assert (interval.low, interval.high) == (0.0, 1.0)


@settings(max_examples=25, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(2, 8), st.integers(1, 5)), elements=st.floats(0, 1)))
def test_the_interval_holds_the_mean_and_is_reproducible(scores) -> None:
    interval = over_seeds(scores, mean, resamples=499, seed=3)
    assert interval.low - 1e-9 <= interval.value <= interval.high + 1e-9
    assert over_seeds(scores, mean, resamples=499, seed=3) == interval
