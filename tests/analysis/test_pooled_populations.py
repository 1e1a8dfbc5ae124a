"""The population as a level above the seed: pooled summaries and paired differences against hand-computed numbers."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from analysis.populations import member_kinds, pool
from analysis.report import build_report
from analysis.summaries import POPULATION_ID, UNIT, adaptation_auc, paired_difference, seed_summary, unit_means

# t(0.975, 2) and t(0.975, 5), from tables.
T2, T5 = 4.302653, 2.570582


def pooled_rows(label: str, per_seed: dict[tuple[str, int], tuple[float, float]]) -> list[dict]:
    """Rows of kind `sp`: (population, seed) -> the values with test partners t0 and t1 (the same names in every population)."""
    return [
        {"population": "sp", POPULATION_ID: pid, "label": label, "seed": seed, "partner": f"t{k}", "v": v}
        for (pid, seed), values in per_seed.items()
        for k, v in enumerate(values)
    ]


# Seed means 2, 4 | 5, 7 | 8, 10: population means 3, 6, 9, far apart next to the seeds within each.
SPREAD = {
    ("sp-p0", 0): (1.0, 3.0),
    ("sp-p0", 1): (3.0, 5.0),
    ("sp-p1", 0): (5.0, 5.0),
    ("sp-p1", 1): (7.0, 7.0),
    ("sp-p2", 0): (8.0, 8.0),
    ("sp-p2", 1): (10.0, 10.0),
}


def test_a_pooled_summary_averages_partners_then_seeds_then_takes_the_interval_over_populations() -> None:
    df = pd.DataFrame(pooled_rows("a", SPREAD))
    means = unit_means(df, ["population"], "v")
    assert list(means[UNIT]) == ["sp-p0", "sp-p1", "sp-p2"] and list(means["v"]) == [3.0, 6.0, 9.0]
    row = seed_summary(df, ["population"], "v").iloc[0]
    # Population means 3, 6, 9: mean 6, sd 3, half-width 4.3027 * 3 / sqrt(3) = 7.4524.
    assert (row["mean"], row["n"]) == (6.0, 3)
    assert (row["lo"], row["hi"]) == pytest.approx((6 - 7.452417, 6 + 7.452417), abs=1e-5)


def test_the_pooled_interval_is_wider_than_one_over_seeds_that_ignores_the_populations() -> None:
    df = pd.DataFrame(pooled_rows("a", SPREAD))
    pooled = seed_summary(df, ["population"], "v").iloc[0]
    # Ignoring populations: seed means 2, 4, 5, 7, 8, 10 (mean 6, sd sqrt(8.4) = 2.8983) as six units,
    # half-width 2.5706 * 2.8983 / sqrt(6) = 3.0416; the seeds of one population are not independent of each other.
    ignored = seed_summary(
        df.drop(columns=POPULATION_ID).assign(seed=df[POPULATION_ID] + df["seed"].astype(str)), ["population"], "v"
    )
    ignored = ignored.iloc[0]
    assert (ignored["mean"], ignored["n"]) == (6.0, 6)
    assert ignored["hi"] - ignored["mean"] == pytest.approx(T5 * 8.4**0.5 / 6**0.5, abs=1e-5)
    assert pooled["hi"] - pooled["lo"] > 2 * (ignored["hi"] - ignored["mean"])


def test_a_group_of_one_population_keeps_the_seed_as_its_unit() -> None:
    df = pd.DataFrame(pooled_rows("a", {k: v for k, v in SPREAD.items() if k[0] == "sp-p0"}))
    row = seed_summary(df, ["population"], "v").iloc[0]
    # Seed means 2 and 4: n = 2 seeds, half-width 12.7062 * sqrt(2) / sqrt(2) = 12.7062.
    assert (row["mean"], row["n"]) == (3.0, 2)
    assert row["hi"] == pytest.approx(3 + 12.706205, abs=1e-5)
    # The same numbers as without the column: one-population results read as before.
    plain = seed_summary(df.drop(columns=POPULATION_ID), ["population"], "v").iloc[0]
    assert list(plain[["mean", "lo", "hi", "n"]]) == list(row[["mean", "lo", "hi", "n"]])


def test_a_pooled_paired_difference_pairs_within_population_seed_and_partner() -> None:
    # B's rows are A's plus a difference set per (population, seed, partner); partner and seed names repeat across
    # populations, so pairing across populations would mix them. Differences per seed: p0 0.2, 0.0 (mean 0.1);
    # p1 0.2, 0.4 (0.3); p2 0.5, 0.5 (0.5). Population means 0.1, 0.3, 0.5: mean 0.3, sd 0.2,
    # half-width 4.3027 * 0.2 / sqrt(3) = 0.49683, n = 3 populations.
    diffs = {
        ("sp-p0", 0): (0.1, 0.3),
        ("sp-p0", 1): (0.0, 0.0),
        ("sp-p1", 0): (0.2, 0.2),
        ("sp-p1", 1): (0.4, 0.4),
        ("sp-p2", 0): (0.5, 0.5),
        ("sp-p2", 1): (0.6, 0.4),
    }
    a = {k: tuple(v + 10 * i for v in SPREAD[k]) for i, k in enumerate(SPREAD)}
    b = {k: tuple(x - d for x, d in zip(a[k], diffs[k])) for k in a}
    df = pd.DataFrame(pooled_rows("A", a) + pooled_rows("B", b))
    mean, lo, hi, n = paired_difference(df, "A", "B", "v")
    assert (mean, n) == (pytest.approx(0.3), 3)
    assert (lo, hi) == pytest.approx((0.3 - 0.496825, 0.3 + 0.496825), abs=1e-5)


def test_adaptation_auc_keeps_each_curves_population() -> None:
    curves = pd.DataFrame(
        [
            {"game": "g", "population": "sp", POPULATION_ID: pid, "label": "a", "run": "r", "seed": 0, "partner": "t0"}
            | {"steps": step, "mean_return": ret, "exact_return": None}
            for pid, ret in (("sp-p0", 1.0), ("sp-p1", 3.0))
            for step in (0, 10)
        ]
    )
    auc = adaptation_auc(curves)
    assert list(auc[POPULATION_ID]) == ["sp-p0", "sp-p1"] and list(auc["auc"]) == [1.0, 3.0]


def test_pool_names_the_kind_and_keeps_each_member_and_leaves_a_folder_without_groups_alone() -> None:
    kinds = member_kinds([{"population_groups": {"sp": ["sp-p0", "sp-p1"]}}, {"game": "other"}])
    assert kinds == {"sp-p0": "sp", "sp-p1": "sp"}
    frame = pd.DataFrame({"population": ["sp-p0", "sp-p1", "hand"], "v": [1, 2, 3]})
    pooled = pool(frame, kinds)
    assert list(pooled["population"]) == ["sp", "sp", "hand"] and list(pooled[POPULATION_ID]) == ["sp-p0", "sp-p1", "hand"]
    assert pool(frame, member_kinds([{"game": "bandit"}])) is frame


def write_member_curves(game_dir: Path, member: str, values: dict[str, float], offset: float) -> None:
    """Flat adaptation curves of population `member`: AUC = value + offset + 0.1 * seed on seeds 0, 1, partners at -/+ 0.1."""
    (game_dir / "adaptation").mkdir(parents=True, exist_ok=True)
    for label, value in values.items():
        method = label if label in ("agg", "maml", "no_task_logits") else "modular"
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for seed in range(2):
            for k, shift in ((0, -0.1), (1, 0.1)):
                v = value + offset + 0.1 * seed + shift
                rows += [f"runs/{member}__{label}/T{seed},{method},0.5,,{seed},test-{k},{step},{v},0.01," for step in (0, 640)]
        (game_dir / "adaptation" / f"{member}__{label}.csv").write_text("\n".join(rows) + "\n")


def test_the_report_pools_the_populations_of_a_kind_and_flags_fewer_seeds_than_declared(tmp_path: Path) -> None:
    game = tmp_path / "repro" / "hanabi"
    members = [f"hanabi-selfplay-p{p}" for p in range(3)]
    game.mkdir(parents=True)
    plan = {
        "game": "hanabi",
        "seeds": [0, 1],
        "quick": False,
        "declared_seeds": 5,
        "population_groups": {"hanabi-selfplay": members},
    }
    (game / "plan.json").write_text(json.dumps(plan))
    # Ours − BaselineAgg is 0.1, 0.2, 0.6 by population (the same on both seeds): mean 0.3, sd 0.26458,
    # half-width 4.3027 * 0.26458 / sqrt(3) = 0.65726.
    for member, offset, gap in zip(members, (0.0, 1.0, 2.0), (0.1, 0.2, 0.6)):
        write_member_curves(game, member, {"modular-lam0.5": 3.0 + gap, "agg": 3.0}, offset)
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    assert "ours λ=0.5 − BaselineAgg +0.300 [-0.357, +0.957] (n=3)" in text
    assert "- hanabi: `hanabi-selfplay` pools 3 independently trained self-play populations" in text
    assert "the interval is over the population means (n = populations)" in text.split("## What was found")[0]
    assert "- hanabi: the plan declared 5 seeds per claim before the run; this run has 2. **Fewer than declared" in text
    assert "hanabi: 2 seeds run of the 5 the plan declared its claims need" in text
