"""`rllib-conv pair` with scripted seats: the seat syntax, the game the seats agree on, the bandit's exact return.

Trained-ego seats (`RUN:ego@NAME`, `RUN:task`) are tested against the evaluation code in
tests/test_cli_outputs.py, which trains a tiny ego.
"""

from __future__ import annotations

import pandas as pd
import pytest

from rllib_conv.cli import main
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.pipelines.pair import pair, pair_game, seat
from rllib_conv.pipelines.pair_config import PairConfig, split_seat


def test_a_seat_splits_at_its_first_colon_only() -> None:
    assert split_seat("bandit_convention:{arms: [0, 1]}") == ("bandit_convention", "{arms: [0, 1]}")
    assert split_seat("runs/x/trial:ego@hand-train-0") == ("runs/x/trial", "ego@hand-train-0")
    with pytest.raises(ValueError, match="expected SOURCE:WHAT"):
        split_seat(":task")


def test_a_population_member_and_a_scripted_kind_become_the_same_partner() -> None:
    member, scripted = seat("bandit-s1-hand:hand-train-2"), seat("bandit_convention:{arms: [4, 1, 2, 3]}")
    assert isinstance(member.player, BanditConventionPartner) and member.player.arms == [4, 1, 2, 3]
    assert scripted.player.arms == member.player.arms
    assert member.game == ("bandit", {"symmetric": 1, "new_task": False}) and scripted.game is None


@pytest.mark.parametrize(
    ("other", "exact"),
    [
        ("bandit_convention:{arms: [0, 1, 2, 3]}", 1.0),  # the same convention
        ("bandit_convention:{arms: [4, 1, 2, 3]}", 0.75),  # context 0 missed, the 3 rule contexts met
        ("bandit_convention:{arms: [4, 5, 6, 7]}", 0.0),  # every context missed
    ],
)
def test_the_exact_bandit_return_counts_the_contexts_where_the_players_meet_on_a_prize(other, exact) -> None:
    table = pair(PairConfig(seats=["bandit-s1-hand:hand-train-0", other], episodes=400, seed=3))
    row = table.iloc[0]
    assert row["exact_return"] == pytest.approx(exact)
    assert abs(row["mean_return"] - exact) <= 4 * row["stderr"] + 1e-9  # sampled episodes agree with the exact value
    assert (row["seat_0"], row["seat_1"], row["episodes"], row["seed"]) == ("bandit-s1-hand:hand-train-0", other, 400, 3)


def test_the_new_task_moves_the_rule_arms_so_an_old_convention_misses_them() -> None:
    old_rules = "bandit_convention:{arms: [0, 1, 2, 3]}"
    row = pair(PairConfig(seats=[old_rules, "bandit-s1-hand-newtask:hand-train-0"], episodes=10)).iloc[0]
    assert row["env_config"] == str({"symmetric": 1, "new_task": True})
    assert row["exact_return"] == pytest.approx(0.25)  # only the symmetric context still pays


def test_the_game_comes_from_the_seats_or_from_env_and_env_config() -> None:
    s1, s2 = seat("bandit-s1-hand:hand-train-0"), seat("bandit-s2-hand:hand-train-0")
    scripted = seat("bandit_convention:{arms: [0, 1, 2, 3]}")
    assert pair_game([scripted, s1]) == ("bandit", {"symmetric": 1, "new_task": False})
    with pytest.raises(ValueError, match="different bandit settings"):
        pair_game([s1, s2])
    assert pair_game([s1, s2], env_config={"symmetric": 2}) == ("bandit", {"symmetric": 2})
    with pytest.raises(ValueError, match="no seat names a game"):
        pair_game([scripted, scripted])
    assert pair_game([scripted, scripted], env="bandit") == ("bandit", {})


def test_a_partner_that_does_not_fit_the_game_is_an_error_naming_it() -> None:
    with pytest.raises(ValueError, match="knows 2 contexts"):
        pair(PairConfig(seats=["bandit_convention:{arms: [0, 1]}", "bandit-s1-hand:hand-train-0"], episodes=20))


def test_pair_on_the_command_line_writes_one_csv_named_after_the_seats(tmp_path, capsys) -> None:
    argv = [
        "pair",
        "bandit-s2-hand:hand-train-1",
        "bandit_convention:{arms: [0, 5, 2, 3]}",
        "--episodes",
        "30",
        "--out",
        str(tmp_path),
    ]
    assert main(argv) == 0
    path = tmp_path / "bandit-s2-hand-hand-train-1__bandit_convention-_arms_0,_5,_2,_3.csv"
    assert capsys.readouterr().out.strip().splitlines()[-1] == f"wrote {path}"
    row = pd.read_csv(path).iloc[0]
    assert (row["env"], row["episodes"], row["exact_return"]) == ("bandit", 30, 1.0)
    assert main([*argv, "--name", "mine"]) == 0
    assert (tmp_path / "mine.csv").is_file()


HEURISTICS = ["lbf_heuristic:{rule: H1}", "lbf_heuristic:{rule: H2}", "lbf_heuristic:{rule: H4}"]


def test_three_heuristic_foragers_fill_the_three_seats_of_lbf_and_collect_food() -> None:
    row = pair(PairConfig(seats=HEURISTICS, env="lbf", episodes=40, seed=2)).iloc[0]
    assert [row[f"seat_{i}"] for i in range(3)] == HEURISTICS and row["env"] == "lbf"
    assert 0.0 < row["mean_return"] <= 1.0 and row["stderr"] > 0  # the team's share of the food, from 0 to 1
    assert pd.isna(row["exact_return"])  # no exact return for this game
    again = pair(PairConfig(seats=HEURISTICS, env="lbf", episodes=40, seed=2)).iloc[0]
    assert again["mean_return"] == row["mean_return"]  # one seed, one result


def test_four_foragers_play_once_the_game_has_four_players() -> None:
    four = [f"lbf_heuristic:{{rule: H{i}, players: 4}}" for i in range(1, 5)]
    row = pair(PairConfig(seats=four, env="lbf", env_config={"players": 4}, episodes=10)).iloc[0]
    assert row["seat_3"] == four[3] and 0.0 <= row["mean_return"] <= 1.0
    # Foragers built for 3 players misread a 4-player game's observations: refused, saying what to give them.
    with pytest.raises(ValueError, match="give the partner the env's food and players"):
        pair(PairConfig(seats=[*HEURISTICS, HEURISTICS[0]], env="lbf", env_config={"players": 4}, episodes=2))


@pytest.mark.parametrize(
    ("seats", "odd"),
    [(HEURISTICS[:2], "player_2 has none"), ([*HEURISTICS, HEURISTICS[0]], "'lbf_heuristic:{rule: H1}' has no agent")],
)
def test_a_wrong_seat_count_is_refused_naming_the_seats_and_writes_nothing(tmp_path, capsys, seats, odd) -> None:
    assert main(["pair", *seats, "--env", "lbf", "--episodes", "2", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"lbf {{}} has 3 seats (player_0, player_1, player_2), got {len(seats)} SEATs ({odd})" in err
    assert "give one SEAT per agent" in err and not (tmp_path / "out").exists()
