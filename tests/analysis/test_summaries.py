"""The statistics of `analysis.summaries`, each against a case computed by hand: seed-level intervals, paired and unpaired differences."""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd
import pytest

from analysis import loaders
from analysis.summaries import (
    adaptation_auc,
    curve_band,
    first_try_difference,
    mean_ci,
    paired_difference,
    seed_summary,
    seeds_for_half_width,
    summarise,
    uniform_prior_return,
    unpaired_difference,
    value_column,
    with_value,
)

FIXTURE = Path(__file__).parent / "fixtures" / "repro"


def rows(label: str, values: dict[tuple[int, str], float]) -> list[dict]:
    """One row per (seed, partner) -> value of method `label`."""
    return [{"population": "p", "label": label, "seed": s, "partner": q, "v": v} for (s, q), v in values.items()]


def test_mean_ci_known_values() -> None:
    # [1, 2, 3, 4]: mean 2.5, sample sd 1.2910, t(0.975, 3) = 3.1824, half-width 3.1824 * 1.2910 / 2 = 2.0542.
    mean, lo, hi, n = mean_ci([1, 2, 3, 4])
    assert (mean, n) == (2.5, 4)
    assert lo == pytest.approx(0.4458, abs=1e-4) and hi == pytest.approx(4.5542, abs=1e-4)
    # Two units: t(0.975, 1) = 12.7062; [0, 1] has sd 0.7071, half-width 12.7062 * 0.7071 / 1.4142 = 6.3531.
    assert mean_ci([0.0, 1.0])[1:3] == pytest.approx((0.5 - 6.3531, 0.5 + 6.3531), abs=1e-4)
    mean, lo, hi, n = mean_ci([0.7, float("nan")])
    assert (mean, n) == (0.7, 1) and math.isnan(lo) and math.isnan(hi)
    assert mean_ci([])[3] == 0


def test_summarise_groups() -> None:
    df = pd.DataFrame({"g": ["a", "a", "b"], "v": [1.0, 3.0, 5.0]})
    s = summarise(df, ["g"], "v").set_index("g")
    assert s.loc["a", "mean"] == 2.0 and s.loc["a", "n"] == 2 and math.isnan(s.loc["b", "lo"])


def test_two_seeds_with_identical_partner_means_give_a_zero_width_interval() -> None:
    # Seed 0: partners 0.2 and 0.6 (mean 0.4); seed 1: 0.3 and 0.5 (mean 0.4). Over the four curves the
    # interval would be 0.4 +- 3.1824 * 0.1826 / 2 = +-0.29; over the two seeds it has no width at all.
    df = pd.DataFrame(rows("m", {(0, "a"): 0.2, (0, "b"): 0.6, (1, "a"): 0.3, (1, "b"): 0.5}))
    s = seed_summary(df, ["label"], "v").iloc[0]
    assert (s["mean"], s["lo"], s["hi"], s["n"]) == pytest.approx((0.4, 0.4, 0.4, 2))
    curves = summarise(df, ["label"], "v").iloc[0]
    assert curves["n"] == 4 and curves["hi"] - curves["lo"] == pytest.approx(2 * 0.2906, abs=1e-3)


def test_seed_summary_is_the_t_interval_over_seed_means() -> None:
    # Seed means 2, 4, 6 (seed 0 from partners 1 and 3): mean 4, sd 2, t(0.975, 2) = 4.3027,
    # half-width 4.3027 * 2 / sqrt(3) = 4.9683.
    df = pd.DataFrame(rows("m", {(0, "a"): 1.0, (0, "b"): 3.0, (1, "a"): 4.0, (1, "b"): 4.0, (2, "a"): 6.0, (2, "b"): 6.0}))
    s = seed_summary(df, ["label"], "v").iloc[0]
    assert s["n"] == 3 and s["mean"] == pytest.approx(4.0)
    assert (s["lo"], s["hi"]) == pytest.approx((4 - 4.9683, 4 + 4.9683), abs=1e-4)


def test_paired_difference_pairs_seed_and_partner() -> None:
    a = {(0, "a"): 0.9, (0, "b"): 0.7, (1, "a"): 0.8, (1, "b"): 0.8}
    b = {(0, "a"): 0.5, (0, "b"): 0.5, (1, "a"): 0.6, (1, "b"): 0.4}
    df = pd.DataFrame(rows("A", a) + rows("B", b))
    # Seed 0: differences 0.4 and 0.2 (mean 0.3); seed 1: 0.2 and 0.4 (mean 0.3): 0.3 with no width.
    assert paired_difference(df, "A", "B", "v") == pytest.approx((0.3, 0.3, 0.3, 2))
    assert paired_difference(df, "B", "A", "v") == pytest.approx((-0.3, -0.3, -0.3, 2))
    # B lacks (seed 1, partner b): seed 1 keeps only its partner a (0.2); seed means 0.3 and 0.2,
    # mean 0.25, sd 0.0707, half-width 12.7062 * 0.0707 / sqrt(2) = 0.6353.
    mean, lo, hi, n = paired_difference(df[~((df["label"] == "B") & (df["seed"] == 1) & (df["partner"] == "b"))], "A", "B", "v")
    assert (mean, n) == pytest.approx((0.25, 2)) and (lo, hi) == pytest.approx((0.25 - 0.6353, 0.25 + 0.6353), abs=1e-4)


def test_pairing_is_more_powerful_than_comparing_independent_groups() -> None:
    # Seeds differ a lot (1, 2, 3) but A is always B + 0.1: the seed-level intervals of A and B overlap
    # widely, while the paired difference is 0.1 on every seed.
    base = {(s, "a"): float(s) for s in (1, 2, 3)}
    df = pd.DataFrame(rows("A", {k: v + 0.1 for k, v in base.items()}) + rows("B", base))
    s = seed_summary(df, ["label"], "v").set_index("label")
    assert s.loc["A", "lo"] < s.loc["B", "hi"]
    assert paired_difference(df, "A", "B", "v") == pytest.approx((0.1, 0.1, 0.1, 3))


def test_paired_difference_with_one_seed_or_nothing_shared_has_no_interval() -> None:
    df = pd.DataFrame(rows("A", {(0, "a"): 1.0, (0, "b"): 0.0}) + rows("B", {(0, "a"): 0.5, (0, "b"): 0.5}))
    mean, lo, hi, n = paired_difference(df, "A", "B", "v")
    assert (mean, n) == (0.0, 1) and math.isnan(lo) and math.isnan(hi)
    mean, lo, hi, n = paired_difference(df, "A", "C", "v")
    assert n == 0 and math.isnan(mean)


def test_paired_difference_on_the_seed_alone() -> None:
    # Marginals: one distance per trained ego. Differences per seed 0.2, 0.4, 0.3: mean 0.3, sd 0.1,
    # half-width 4.3027 * 0.1 / sqrt(3) = 0.2484.
    df = pd.DataFrame({"label": ["A"] * 3 + ["B"] * 3, "seed": [0, 1, 2] * 2, "d": [0.5, 0.6, 0.6, 0.3, 0.2, 0.3]})
    mean, lo, hi, n = paired_difference(df, "A", "B", "d", within=())
    assert (mean, n) == pytest.approx((0.3, 3)) and (lo, hi) == pytest.approx((0.3 - 0.2484, 0.3 + 0.2484), abs=1e-4)


def test_unpaired_difference_is_welchs_interval() -> None:
    # x = 1, 2, 3 (var 1), y = 0, 0.5, 1.5 (var 0.5833): difference 1.3333, se sqrt(1/3 + 0.5833/3) = 0.7265,
    # Welch's df = 0.5278^2 / ((1/3)^2 / 2 + 0.1944^2 / 2) = 3.741, t(0.975, 3.741) = 2.8537, half-width 2.0734.
    mean, lo, hi, n = unpaired_difference([1.0, 2.0, 3.0], [0.0, 0.5, 1.5])
    assert (mean, n) == pytest.approx((4 / 3, 3))
    assert (lo, hi) == pytest.approx((4 / 3 - 2.0734, 4 / 3 + 2.0734), abs=1e-3)
    # Identical seeds: no spread, a zero-width interval at the difference.
    assert unpaired_difference([1.0, 1.0], [0.25, 0.25]) == pytest.approx((0.75, 0.75, 0.75, 2))
    assert math.isnan(unpaired_difference([1.0], [0.0, 1.0])[1])


def test_curve_band_is_seed_level() -> None:
    # Seeds 0 and 1, partners a and b, two points. Point 0: seed means (0.2 + 0.6) / 2 = 0.4 and
    # (0.3 + 0.5) / 2 = 0.4 -> 0.4 with no width; point 1: seed means 0.6 and 0.8 -> mean 0.7, sd 0.1414,
    # half-width 12.7062 * 0.1414 / sqrt(2) = 1.2706.
    base = {"game": "bandit", "population": "p", "label": "m"}
    values = {(0, "a"): (0.2, 0.5), (0, "b"): (0.6, 0.7), (1, "a"): (0.3, 0.9), (1, "b"): (0.5, 0.7)}
    rows_ = [
        {**base, "run": f"r{s}", "seed": s, "partner": q, "steps": step, "mean_return": v[i]}
        for (s, q), v in values.items()
        for i, step in enumerate((0, 16))
    ]
    band = curve_band(pd.DataFrame(rows_)).set_index("steps")
    assert band.loc[0, ["mean", "lo", "hi", "n"]].tolist() == pytest.approx([0.4, 0.4, 0.4, 2])
    assert band.loc[16, ["mean", "lo", "hi"]].tolist() == pytest.approx([0.7, 0.7 - 1.2706, 0.7 + 1.2706], abs=1e-4)


def test_curve_band_matches_points_by_order_not_step_count() -> None:
    # Two Hanabi-like curves of one seed whose evaluations land a few steps apart: 3 points each.
    base = {"game": "hanabi", "population": "p", "label": "m", "run": "r", "seed": 0}
    rows_ = [{**base, "partner": "a", "steps": s, "mean_return": v} for s, v in [(0, 1.0), (640, 2.0), (1281, 3.0)]] + [
        {**base, "partner": "b", "steps": s, "mean_return": v} for s, v in [(0, 3.0), (642, 4.0), (1287, 5.0)]
    ]
    band = curve_band(pd.DataFrame(rows_))
    assert band["steps"].tolist() == [0, 641, 1284]
    assert band["mean"].tolist() == [2.0, 3.0, 4.0] and band["n"].tolist() == [1, 1, 1]  # one seed: no band
    assert band["lo"].isna().all()


def test_first_try_difference_pairs_people() -> None:
    # Three pairs; first try in A: 1, 1, 0; in B: 0, 1, 0 -> differences 1, 0, 0: mean 1/3, sd 0.5774,
    # half-width 4.3027 * 0.5774 / sqrt(3) = 1.4342. The fifth try is ignored.
    study = pd.DataFrame(
        [
            {"pair_id": p, "task": "test", "context": c, "try": 1, "coordinated": v}
            for c, vs in (("A", (1, 1, 0)), ("B", (0, 1, 0)))
            for p, v in zip("xyz", vs)
        ]
        + [{"pair_id": "x", "task": "test", "context": "B", "try": 5, "coordinated": 1}]
    )
    mean, lo, hi, n = first_try_difference(study, ("test", "A"), ("test", "B"))
    assert (mean, n) == pytest.approx((1 / 3, 3)) and (lo, hi) == pytest.approx((1 / 3 - 1.4342, 1 / 3 + 1.4342), abs=1e-4)


def test_value_column_prefers_exact() -> None:
    df = pd.DataFrame({"mean_return": [0.5, 0.6], "exact_return": [0.55, 0.65]})
    assert value_column(df) == "exact_return"
    assert value_column(df.assign(exact_return=[0.5, float("nan")])) == "mean_return"
    assert value_column(df.drop(columns="exact_return")) == "mean_return"


def test_adaptation_auc_on_fixture() -> None:
    auc = adaptation_auc(loaders.load_adaptation(FIXTURE)).set_index("label")
    # modular-lam0.5's exact returns at steps 0..64: 0.46471, 0.55093, 0.67293, 0.77318, 0.83657; mean 0.65966.
    assert auc.loc["modular-lam0.5", "auc"] == pytest.approx(0.659664, abs=1e-6)
    assert auc.loc["modular-lam0.5", "start"] == pytest.approx(0.4647056758403778)
    assert auc.loc["modular-lam0.5", "end"] == pytest.approx(0.8365700840950012)
    assert auc.loc["agg", "points"] == 5 and auc.loc["agg", "last_step"] == 64
    assert (auc["value_source"] == "exact_return").all()
    assert set(with_value(loaders.load_zeroshot(FIXTURE))["value_source"]) == {"exact_return"}


def test_uniform_prior_adapter_known_answers() -> None:
    # 4 contexts, 2 symmetric: before any episode 2/4 * 1 + 2/4 * 1/2 = 0.75.
    assert uniform_prior_return(4, 2, 0) == pytest.approx(0.75)
    # after 1 episode each symmetric context is unseen with prob 3/4: 0.5 + 0.5 * (1 - 3/8) = 0.8125.
    assert uniform_prior_return(4, 2, 1) == pytest.approx(0.8125)
    assert uniform_prior_return(4, 0, 0) == 1.0 and uniform_prior_return(4, 4, 10_000) == pytest.approx(1.0)
    with pytest.raises(ValueError, match="symmetric"):
        uniform_prior_return(4, 5, 0)
    # Never above the full-information return (the partner's arm known in every context), rising with evidence.
    for m in range(5):
        returns = [uniform_prior_return(4, m, t) for t in range(0, 300, 7)]
        assert all(a <= b <= 1.0 for a, b in zip(returns, returns[1:]))


def test_seeds_for_half_width_known_values() -> None:
    # sd 0.0138: t(0.975, 8) * 0.0138 / 3 = 2.3060 * 0.0046 = 0.01061 >= 0.01 at 9 seeds;
    # t(0.975, 9) * 0.0138 / sqrt(10) = 2.2622 * 0.004364 = 0.00987 < 0.01 at 10.
    assert seeds_for_half_width(0.0138, 0.01) == 10
    # sd 0.0102: 2.4469 * 0.0102 / sqrt(7) = 0.00943 at 7; 2.5706 * 0.0102 / sqrt(6) = 0.01070 at 6.
    assert seeds_for_half_width(0.0102, 0.01) == 7
    assert seeds_for_half_width(0.0, 0.01) == 2  # no spread: the smallest n with an interval
    with pytest.raises(ValueError, match="half_width > 0"):
        seeds_for_half_width(0.01, 0.0)
