"""`rllib-conv evaluate` in a game of three seats (Level-Based Foraging): teams of the set's partners, declared bounds.

Known answers: a scripted ego meets every team of the set's partners, one per partner seat, and
its return there is the return `seated_return` gives for the same seats and episodes; the
normalised score is that return over the bound the set declares for the team.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
import yaml

from rllib_conv.cli import main
from rllib_conv.partners.evaluation_sets import ROLES, disjoint, load_set, shipped_set
from rllib_conv.partners.lbf import LBFHeuristic
from rllib_conv.pipelines.evaluate import Player, score_table
from rllib_conv.pipelines.evaluate_config import EvaluateConfig, TrainedEgo, check
from rllib_conv.training.evaluate import seated_return

pytest.importorskip("lbforaging")

SEATS = ["player_1", "player_2"]
BASE = {
    "name": "lbf-test",
    "role": "heldout",
    "env": "lbf",
    "env_config": {"players": 3},
    "partner_agent": SEATS,
    "built_by": "by hand, for the test",
    "partners": [
        {"name": "H3", "kind": "lbf_heuristic", "params": {"rule": "H3"}},
        {"name": "H4", "kind": "lbf_heuristic", "params": {"rule": "H4"}},
    ],
}
TEAMS = ["H3+H3", "H3+H4", "H4+H3", "H4+H4"]


def write(folder: Path, data: dict) -> Path:
    path = folder / "set.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_a_scripted_ego_meets_every_team_and_is_normalised_by_the_declared_bound(tmp_path) -> None:
    bounds = dict(zip(TEAMS, [0.5, 0.6, 0.7, 0.8]))
    eval_set = load_set(write(tmp_path, {**BASE, "bounds": bounds, "bounds_by": "made up for the test"}))
    pop = eval_set.resolve()
    ego = LBFHeuristic("H1", rule="H1")
    player = Player(TrainedEgo("h1", Path("exp/t/seed=0"), 0), "ego", ego)
    table = score_table([player], pop, episodes=16, seed=3, declared=eval_set.bounds).set_index("partner")
    assert list(table.index) == TEAMS
    assert (table["bound_source"] == "declared").all() and (table["source"] == "sampled").all()
    assert table.loc["H3+H4", "kind"] == "lbf_heuristic+lbf_heuristic"
    for team, (a, b) in zip(TEAMS, [("H3", "H3"), ("H3", "H4"), ("H4", "H3"), ("H4", "H4")]):
        seats = {"player_0": ego, "player_1": LBFHeuristic(a, rule=a), "player_2": LBFHeuristic(b, rule=b)}
        direct = seated_return(seats, "lbf", {"players": 3}, episodes=16, seed=3)["mean"]
        assert table.loc[team, "return"] == pytest.approx(direct), team
        assert table.loc[team, "normalised"] == pytest.approx(direct / bounds[team]), team


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ({"bounds": {"H3+H3": 0.5}}, "bounds_by: say how the declared bounds were measured"),
        ({"bounds": {"H3+H9": 0.5}, "bounds_by": "x"}, r"bounds for \['H3\+H9'\], which are not partners \(or teams\)"),
        ({"bounds": {"H3+H3": 0.0}, "bounds_by": "x"}, "bounds.H3\\+H3: Input should be greater than 0"),
    ],
)
def test_bad_declared_bounds_name_the_file_and_the_problem(tmp_path, extra, message) -> None:
    path = write(tmp_path, {**BASE, **extra})
    with pytest.raises(ValueError, match=message) as err:
        load_set(path).resolve()
    assert str(path) in str(err.value)


def test_a_team_without_a_bound_is_refused_naming_it(tmp_path) -> None:
    eval_set = load_set(write(tmp_path, {**BASE, "bounds": {"H3+H3": 0.5}, "bounds_by": "x"}))
    with pytest.raises(ValueError, match=r"partner 'H3\+H4' \(kind lbf_heuristic\+lbf_heuristic\) has no exact best-response"):
        score_table([], eval_set.resolve(), 4, 0, declared=eval_set.bounds)


def test_the_shipped_lbf_sets_are_disjoint_and_bound_every_team() -> None:
    sets = {role: shipped_set("lbf", role) for role in ROLES}
    assert disjoint(sets["heldout"].resolve(), sets["validation"].resolve())
    for role, eval_set in sets.items():
        pop = eval_set.resolve()
        assert pop.partner_agents == SEATS and eval_set.bounds_by.strip(), role
        assert sorted(eval_set.bounds) == sorted(name for name, _ in pop.teams()), role
        assert all(0 < b <= 1 for b in eval_set.bounds.values()), role  # the share of the food: at most all of it


@pytest.mark.slow
def test_a_three_seat_ego_is_evaluated_against_the_held_out_teams_end_to_end(lbf_ego: Path, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    found = check(EvaluateConfig(runs=[str(lbf_ego)]))
    assert found.partners.partner_agents == SEATS
    assert main(["evaluate", str(lbf_ego), "--episodes", "4", "--resamples", "200", "--out", "ev", "--name", "lbf"]) == 0
    folder = tmp_path / "ev" / "lbf"
    table = pd.read_csv(folder / "scores.csv")
    # The modular ego has no head for a held-out team: its task module plays every team.
    assert sorted(table["partner"]) == TEAMS and set(table["module"]) == {"task"} and (table["episodes"] == 4).all()
    record = json.loads((folder / "summary.json").read_text())
    assert record["bounds"] == shipped_set("lbf", "heldout").bounds
    assert record["eval_set"]["bounds_by"] == shipped_set("lbf", "heldout").bounds_by
    assert record["aggregates"][0]["mean"] == pytest.approx((table["return"] / table["bound"]).mean())
