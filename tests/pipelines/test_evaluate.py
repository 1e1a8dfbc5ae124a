"""`rllib-conv evaluate` (`pipelines/evaluate.py`): known answers with scripted egos, the refusals, and one tiny trained ego end to end.

A scripted ego that IS the best response to a partner scores exactly 1.0 against it; one
that meets a partner in 3 of 4 bandit contexts scores 0.75 / bound.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from rllib_conv.cli import main
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.base import Partner
from rllib_conv.partners.blocks import BlocksLeader
from rllib_conv.partners.evaluation_sets import shipped_set
from rllib_conv.partners.kinds import register_kind
from rllib_conv.pipelines.evaluate import SCORE_COLUMNS, SUMMARY_COLUMNS, Player, draw, score_table, summarise
from rllib_conv.pipelines.evaluate_config import TrainedEgo
from rllib_conv.pipelines.pair import pair
from rllib_conv.pipelines.pair_config import PairConfig
from tests.helpers import tiny_experiment


def scripted(player: Partner, seed: int = 0, agent: str = "scripted") -> Player:
    return Player(TrainedEgo(agent, Path(f"exp/trial/seed={seed}"), seed), "ego", player)


def test_the_best_response_to_each_partner_scores_exactly_one() -> None:
    pop = shipped_set("blocks", "heldout").resolve()
    for entry in pop.partners:  # every blocks partner here follows a permutation: its leader is the best response
        leader = BlocksLeader("leader", entry.params["perm"])
        row = score_table([scripted(leader)], pop.model_copy(update={"partners": [entry]}), episodes=8, seed=0).iloc[0]
        assert (row["source"], row["normalised"]) == ("exact", pytest.approx(1.0))


def test_normalised_is_the_exact_return_over_the_bound() -> None:
    pop = shipped_set("bandit", "heldout").resolve()
    table = score_table([scripted(BanditConventionPartner("low-high", [0, 5, 2, 3]))], pop, episodes=8, seed=0)
    assert list(table.columns) == SCORE_COLUMNS and len(table) == len(pop.partners)
    got = table.set_index("partner")
    # conv-low-high: itself; conv-high-low: both symmetric contexts missed; mixed-70: 0.7 and 0.7 of them
    # met, the rules always; slips-20: 0.825 of context 0 and 2, 0.025 of 1 (the high arm), 0.825 of 3.
    expected = {
        "conv-low-high": (1.0, 1.0),
        "conv-high-low": (0.5, 1.0),
        "mixed-70": ((0.7 + 0.7 + 2) / 4, 0.85),
        "slips-20": ((0.825 + 0.025 + 0.825 + 0.825) / 4, 0.825),
        "rule-miss-2": (0.5, 0.75),
    }
    for partner, (ret, bound) in expected.items():
        assert got.loc[partner, "return"] == pytest.approx(ret) and got.loc[partner, "bound"] == pytest.approx(bound)
        assert got.loc[partner, "normalised"] == pytest.approx(ret / bound)
    assert (got["source"] == "exact").all() and (got["episodes"] == 0).all()


@register_kind
class Unsaid(BanditConventionPartner):
    """A bandit ego that plays a convention but does not say so: only sampled episodes can score it."""

    kind = "test_unsaid_convention"
    deterministic = False


def test_an_ego_without_action_probabilities_is_scored_on_sampled_episodes() -> None:
    pop = shipped_set("bandit", "validation").resolve()
    table = score_table([scripted(Unsaid("e", [0, 1, 2, 3]))], pop, episodes=64, seed=2).set_index("partner")
    assert (table["source"] == "sampled").all() and (table["episodes"] == 64).all()
    assert table.loc["conv-low-low", "normalised"] == 1.0 and table.loc["conv-low-low", "stderr"] == 0.0
    row = table.loc["mixed-60"]  # exact 0.25 * (0.4 + 0.6 + 2) = 0.75
    assert abs(row["return"] - 0.75) <= 4 * row["stderr"] and row["normalised"] == pytest.approx(row["return"] / 0.8)


def test_a_partner_no_ego_can_score_with_or_without_a_known_bound_is_refused() -> None:
    pop = shipped_set("bandit", "heldout").resolve()
    entry = pop.partners[0].model_copy(update={"name": "never", "params": {"arms": [1, 0, 0, 0]}})
    with pytest.raises(ValueError, match="my-set: partner 'never' has a best-response bound of 0"):
        score_table([], pop.model_copy(update={"partners": [entry]}), 8, 0, where="my-set")
    learner = pop.partners[0].model_copy(update={"name": "learner", "kind": Unsaid.kind})
    with pytest.raises(ValueError, match="partner 'learner' .* has no exact best-response bound"):
        score_table([], pop.model_copy(update={"partners": [learner]}), 8, 0, where="my-set")


def test_the_summary_aggregates_over_seeds_per_agent() -> None:
    rows = [
        ["a", f"e{s}", s, "ego", p, "k", v, "exact", 0, 0.0, 1.0, "exact", v]
        for s, values in enumerate([[1.0, 0.5], [0.5, 0.0]])
        for p, v in zip(["p", "q"], values)
    ]
    rows += [["b", "e0", 0, "ego", p, "k", 0.4, "exact", 0, 0.0, 1.0, "exact", 0.4] for p in ("p", "q")]
    summary = summarise(pd.DataFrame(rows, columns=SCORE_COLUMNS), resamples=999).set_index("agent")
    assert list(summary.reset_index().columns) == SUMMARY_COLUMNS
    a, b = summary.loc["a"], summary.loc["b"]
    assert (a["seeds"], a["partners"], a["mean"], a["iqm"]) == (2, 2, 0.5, 0.5)
    assert a["mean_low"] == pytest.approx(0.25) and a["mean_high"] == pytest.approx(0.75)  # the two seeds' means
    assert b["mean"] == pytest.approx(0.4) and np.isnan(b["mean_low"])  # one seed: no interval


@pytest.mark.slow
def test_a_tiny_trained_ego_is_evaluated_end_to_end(ray_session, tmp_path, monkeypatch) -> None:
    from rllib_conv.pipelines.train import run
    from rllib_conv.training import experiment

    raw = {**tiny_experiment("tiny"), "population": "bandit-s2-hand", "method": "agg", "seed": {"grid_search": [0, 1]}}
    assert not run(experiment.checked(raw), storage=tmp_path / "runs").errors
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", "runs/tiny", "--eval-set", "validation", "--resamples", "500"]) == 0
    folder = tmp_path / "evaluation" / "tiny-validation"
    assert sorted(p.name for p in folder.iterdir()) == ["scores.csv", "summary.json", "summary.png"]
    table = pd.read_csv(folder / "scores.csv")
    assert len(table) == 2 * 5 and sorted(table["seed"].unique()) == [0, 1] and set(table["module"]) == {"ego"}
    record = json.loads((folder / "summary.json").read_text())
    assert record["command"] == "rllib-conv evaluate runs/tiny --eval-set validation --resamples 500"
    assert record["config"]["eval_set"] == "validation" and record["eval_set"]["name"] == "bandit-validation"
    (agg,) = record["aggregates"]
    assert agg["seeds"] == 2 and agg["mean"] == pytest.approx(table["normalised"].mean())
    assert agg["mean_low"] <= agg["mean"] <= agg["mean_high"]
    # The same ego and partner through `pair` give the same exact return.
    row = table.iloc[0]
    trial = tmp_path / "runs" / "tiny" / row["ego"]
    params = yaml.safe_dump(shipped_set("bandit", "validation").resolve().partners[0].params, default_flow_style=True)
    paired = pair(PairConfig(seats=[f"{trial}:ego", f"bandit_convention:{params.strip()}"], episodes=1)).iloc[0]
    assert row["partner"] == "conv-low-low" and row["return"] == pytest.approx(paired["exact_return"])
    # Another module plays when asked: the task module alone.
    assert main(["evaluate", "runs/tiny", "--module", "task", "--resamples", "500"]) == 0
    assert set(pd.read_csv(tmp_path / "evaluation" / "tiny-heldout-module=task" / "scores.csv")["module"]) == {"task"}


COMMITTED = sorted(Path("benchmarks/results").glob("evaluate_*/*/summary.json"))


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: f"{p.parent.parent.name}/{p.parent.name}")
def test_a_committed_evaluation_rebuilds_from_its_scores(path: Path) -> None:
    # The committed scores.csv (one row per ego and partner) is the data; summary.json's numbers must follow from it.
    record = json.loads(path.read_text())
    table = pd.read_csv(path.parent / "scores.csv")
    np.testing.assert_allclose(table["normalised"], table["return"] / table["bound"], rtol=1e-12)
    assert table.drop_duplicates("partner").set_index("partner")["bound"].to_dict() == record["bounds"]
    cfg = record["config"]
    rebuilt = summarise(table, cfg["resamples"], cfg["confidence"], cfg["seed"])
    committed = pd.DataFrame(record["aggregates"])[SUMMARY_COLUMNS]
    pd.testing.assert_frame_equal(rebuilt.reset_index(drop=True), committed, check_exact=False, rtol=1e-12)
    assert (path.parent.parent / "COMMAND").is_file()


def test_the_committed_evaluations_are_found() -> None:
    assert {p.parent.name for p in COMMITTED} >= {"heldout", "validation"}


def test_the_figure_draws_an_interval_that_does_not_hold_its_point_and_one_seed_without_any(tmp_path) -> None:
    # The IQM of 3 seeds lay outside its percentile interval in the 3-seed bandit plan, which failed drawing it as errors.
    rows = [["ours", 3, 4, 0.9, 0.8, 0.95, 0.5, 0.6, 0.8, 1.0], ["agg", 1, 4, 0.7, np.nan, np.nan, 0.7, np.nan, np.nan, 0.8]]
    draw(pd.DataFrame(rows, columns=SUMMARY_COLUMNS), "a set", tmp_path / "summary.png")
    assert (tmp_path / "summary.png").stat().st_size > 0
