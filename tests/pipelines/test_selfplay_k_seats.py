"""Self-play in a game of three seats (Level-Based Foraging): one module plays every seat, and each passing team's module
is a member that sits in either partner seat of the population an ego then trains with."""

from __future__ import annotations

import json

import pytest

from rllib_conv.cli import main
from rllib_conv.common import config_files
from rllib_conv.partners import get
from rllib_conv.pipelines.crossplay import crossplay
from rllib_conv.pipelines.selfplay import game_agents, train_population
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

LBF_YAML = "tune_configs/selfplay_lbf.yaml"


def _config(*overrides: str) -> SelfPlayConfig:
    return config_files.load_checked(LBF_YAML, list(overrides), schema=SelfPlayConfig).first


def test_the_shipped_config_seats_its_members_in_both_partner_seats() -> None:
    cfg = _config()
    assert cfg.shared_seats and cfg.partner_agents == ["player_1", "player_2"]
    assert game_agents(cfg) == ["player_0", "player_1", "player_2"]


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["shared_seats=false"], "partner_agent: several partner seats need shared_seats: true"),
        (["partner_agent=[player_1, player_1]"], "partner_agent: seats must differ"),
    ],
)
def test_several_partner_seats_without_one_shared_module_are_refused(overrides: list[str], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        _config(*overrides)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["partner_agent=player_1"], r"must be a list of 2 of the game's agents \['player_0', 'player_1', 'player_2'\]"),
        (["partner_agent=[player_1, player_5]"], "must be a list of 2 of the game's agents"),
        (["env_config.players=2"], "must be one of the game's two agents"),
    ],
)
def test_partner_seats_that_do_not_leave_the_ego_one_seat_are_refused_naming_them(overrides, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        game_agents(_config(*overrides))


def test_the_cli_refuses_a_partner_seat_too_few_with_exit_2_and_writes_nothing(tmp_path, capsys) -> None:
    argv = ["partners", "train", LBF_YAML, "--set", "partner_agent=player_1", "--out", str(tmp_path / "pops")]
    assert main([*argv, "--storage", str(tmp_path / "runs")]) == 2
    assert "partner_agent 'player_1' must be a list of 2" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_three_seat_teams_learn_and_their_members_train_an_ego_on_every_team(ray_session, tmp_path) -> None:
    overrides = [
        "name=lbf-sp",
        "train_pairs=1",
        "test_pairs=1",
        "fcp=true",  # each team's module before training, beside the one that passed
        "run.timesteps=15000",
        "gate.score=0.1",
        "gate.episodes=50",
        "gate.check_episodes=30",
    ]
    cfg = config_files.checked(config_files.load(LBF_YAML, overrides, schema=SelfPlayConfig), SelfPlayConfig)
    population, report = train_population(cfg, out=tmp_path / "pops", storage=tmp_path / "runs")
    assert report["passed"].all(), report
    assert population.partner_agent == ["player_1", "player_2"]
    by_name = {e.name: e for e in population.partners}
    for team in ("sp00", "sp01"):
        # Before training a greedy team forages by chance; having passed the gate, it collects more.
        assert by_name[f"{team}-init"].score < by_name[team].score, report
    train = [e.name for e in population.entries("train")]
    assert train[0] == "sp00-init" and train[-1] == "sp00"
    # Cross-play seats a column's member in both partner seats: the diagonal is each member's self-play.
    matrix = crossplay(population, population, episodes=10)
    assert list(matrix.index) == list(matrix.columns) == list(by_name) and matrix.columns.name.endswith("(player_1, player_2)")
    assert matrix.loc["sp01", "sp01"] > matrix.loc["sp01-init", "sp01-init"]

    # The members are partners like the heuristic types: an ego trains with every team of two of them.
    exp = {"name": "on-sp", "population": str(tmp_path / "pops" / "lbf-sp"), "model": {"hidden": 8}}
    exp_file = tmp_path / "on-sp.yaml"
    exp_file.write_text(
        json.dumps({**exp, "ppo": {"rollout_per_partner": 50, "num_epochs": 1}, "run": {"timesteps": 600, "eval_episodes": 4}})
    )
    assert main(["train", str(exp_file), "--storage", str(tmp_path / "egos")]) == 0
    (result,) = (tmp_path / "egos" / "on-sp").glob("EgoTrainable_*/result.json")
    last = json.loads(result.read_text().splitlines()[-1])
    teams = [f"{a}+{b}" for a in train for b in train]
    assert len(teams) == len(train) ** 2 >= 4
    for team in teams:
        assert 0.0 <= last[f"eval/mean/{team}"] <= 1.0
    assert get(str(tmp_path / "pops" / "lbf-sp")).partner_agents == ["player_1", "player_2"]
