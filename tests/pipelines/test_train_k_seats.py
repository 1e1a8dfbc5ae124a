"""An ego in a game of three seats (Level-Based Foraging): its setup, a head per team of partners, and a tiny training run."""

from __future__ import annotations

import json

import pytest
import yaml

from rllib_conv.cli import main
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.partners import get
from rllib_conv.partners.lbf import LBFHeuristic
from rllib_conv.partners.population import from_partners
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.ego_setup import resolve, setup_for
from rllib_conv.training.evaluate import load_module
from rllib_conv.training.experiment import ExperimentConfig

TEAMS = ["H1+H1", "H1+H2", "H2+H1", "H2+H2"]


def test_the_lbf_population_seats_its_partners_in_two_seats_and_the_ego_has_a_head_per_team() -> None:
    setup = resolve(ExperimentConfig(population="lbf-heuristics"))
    assert (setup.ego_agent, setup.partner_agents) == ("player_0", ["player_1", "player_2"])
    assert setup.teams == [("H1", "H1"), ("H1", "H2"), ("H2", "H1"), ("H2", "H2")]
    assert setup.head_ids == [f"ego@{t}" for t in TEAMS] and setup.head_for(("H2", "H1")) == "ego@H2+H1"
    agg = resolve(ExperimentConfig(population="lbf-heuristics", method="agg"))
    assert agg.head_ids == ["ego"] and agg.head_for(("H1", "H2")) == "ego"
    assert [e.name for e in get("lbf-heuristics").entries("test")] == ["H3", "H4"]


@pytest.mark.parametrize(
    ("seats", "message"),
    [
        ("player_1", r"must list every seat but the ego's, 2 of the game's 3 agents"),
        (["player_1", "player_1"], r"must list every seat but the ego's"),
        (["player_1", "player_5"], r"must list every seat but the ego's"),
    ],
)
def test_a_population_that_leaves_a_seat_empty_is_refused_naming_it(seats, message: str) -> None:
    pop = from_partners("p", "lbf", {"players": 3}, [LBFHeuristic("H1")], [], partner_agent=seats)
    with pytest.raises(ValueError, match=message):
        setup_for(ExperimentConfig(population="lbf-heuristics"), pop, pop.entries("train"))


def test_a_mapping_function_is_refused_with_several_partner_seats() -> None:
    exp = ExperimentConfig(
        population="lbf-heuristics", mapping={"kind": "function", "function": "tests.modules.mapping_functions:last_partner"}
    )
    with pytest.raises(
        ValueError, match="mapping.function chooses one partner seat's partner; population 'lbf-heuristics' has 2"
    ):
        resolve(exp)


@pytest.mark.slow
def test_the_modular_ego_trains_on_three_seats_and_is_scored_per_team(ray_session, tmp_path) -> None:
    config = tmp_path / "lbf3.yaml"
    tiny = {"name": "lbf3", "population": "lbf-heuristics", "model": {"hidden": 8}}
    config.write_text(yaml.safe_dump({**tiny, "ppo": {"rollout_per_partner": 50, "num_epochs": 1}, "run": {"timesteps": 400}}))
    assert main(["train", str(config), "--storage", str(tmp_path / "runs")]) == 0
    (trial,) = trial_folders(tmp_path / "runs" / "lbf3")
    module = load_module(last_checkpoint(trial))
    assert sorted(module.head_ids()) == [f"ego@{t}" for t in TEAMS]
    (result,) = (tmp_path / "runs" / "lbf3").glob("EgoTrainable_*/result.json")
    last = json.loads(result.read_text().splitlines()[-1])
    for team in TEAMS:  # each head trained with its team and scored with it; returns are shares of the food
        assert 0.0 <= last[f"return/{team}"] <= 1.0 and 0.0 < last[f"eval/mean/{team}"] <= 1.0
    assert last["env_steps"] >= 400
