"""Overcooked-AI: PettingZoo API, seeding, a scripted soup, rewards and shaping, replays from a state, errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from overcooked.mdp.actions import Action, Direction
from overcooked.mdp.overcooked_mdp import OvercookedGridworld, OvercookedState, PlayerState, SoupState
from pettingzoo.test import parallel_api_test, parallel_seed_test
from ray.rllib.utils.pre_checks.env import check_multiagent_environments

from rllib_conv import envs
from rllib_conv.envs.overcooked import (
    ACTIONS,
    CLASSIC_LAYOUTS,
    EAST,
    INTERACT,
    NORTH,
    NUM_ACTIONS,
    SOUTH,
    STAY,
    WEST,
    OvercookedEnv,
    action_index,
    layouts,
    shaping_factor,
)
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv

# cramped_room (x right, y down):     XXPXX   pot (2, 0)
#                                     O  2O   onion dispensers (0, 1) (4, 1); player_1 starts at (3, 1)
#                                     X1  X   player_0 starts at (1, 2) facing north
#                                     XDXSX   dish dispenser (1, 3), serving spot (3, 3)
ONION_TO_POT = [NORTH, WEST, INTERACT, EAST, NORTH, INTERACT]  # from (1, 2): fetch an onion, pot it from (2, 1)
AGAIN = [WEST, INTERACT, EAST, NORTH, INTERACT]  # from (2, 1) facing the pot: one more onion
FETCH_DISH = [WEST, SOUTH, SOUTH, INTERACT, NORTH, EAST, NORTH]  # to (1, 2), face the dispenser, take a dish, back at the pot
SERVE = [INTERACT, SOUTH, EAST, SOUTH, INTERACT]  # take the soup, go to (3, 2), face the serving spot, deliver


def play(env: OvercookedEnv, moves: list[int], partner: int = STAY) -> tuple[float, float, float, int]:
    """Play player_0's `moves` (player_1 plays `partner`); return the sums of player_0's reward, sparse and shaped reward, and the step count."""
    total = sparse = shaped = 0.0
    for move in moves:
        _, rewards, _, _, infos = env.step({"player_0": move, "player_1": partner})
        total += rewards["player_0"]
        sparse += infos["player_0"]["sparse_reward"]
        shaped += infos["player_0"]["shaped_reward"]
    return total, sparse, shaped, len(moves)


def one_soup(env: OvercookedEnv) -> tuple[float, float, float]:
    """Player_0 alone cooks and delivers one onion soup in cramped_room; return its reward, sparse and shaped sums."""
    totals = np.zeros(3)
    for moves in (ONION_TO_POT, AGAIN, AGAIN, FETCH_DISH):
        totals += play(env, moves)[:3]
    # The third onion starts the 20-tick cook on its own (2019 dynamics); wait until the soup is done.
    pot = env.state.objects[(2, 0)]
    totals += play(env, [STAY] * pot.cook_time_remaining)[:3]
    assert env.state.objects[(2, 0)].is_ready
    totals += play(env, SERVE)[:3]
    return tuple(totals)


def test_action_order_is_the_packages_and_indices_round_trip() -> None:
    assert ACTIONS == tuple(Action.ALL_ACTIONS) and NUM_ACTIONS == 6
    assert [ACTIONS[i] for i in (NORTH, SOUTH, EAST, WEST)] == [Direction.NORTH, Direction.SOUTH, Direction.EAST, Direction.WEST]
    assert ACTIONS[STAY] == Action.STAY == (0, 0) and ACTIONS[INTERACT] == Action.INTERACT
    assert [action_index(a) for a in ACTIONS] == list(range(6))
    assert action_index([0, -1]) == NORTH  # the human data's lists read as the package's tuples
    with pytest.raises(ValueError, match="not an Overcooked action"):
        action_index((2, 2))


@pytest.mark.parametrize("layout", CLASSIC_LAYOUTS)
def test_pettingzoo_api_and_seed_on_the_classic_layouts(layout: str) -> None:
    parallel_api_test(envs.make("overcooked", layout=layout), num_cycles=450)  # crosses the 400-step horizon
    parallel_seed_test(lambda: envs.make("overcooked", layout=layout), num_cycles=100)


def test_one_delivered_soup_scores_20_for_both_and_the_known_shaping() -> None:
    env = OvercookedEnv("cramped_room", shaping=1.0)
    env.reset(seed=0)
    total, sparse, shaped = one_soup(env)
    assert sparse == 20.0
    # Shaped: 3 onions potted (3 each), a useful dish pickup (3), the soup picked up (5).
    assert shaped == 3 * 3 + 3 + 5
    assert total == 20.0 + 17.0


def test_shaping_zero_gives_the_sparse_reward_only_and_both_players_share_it() -> None:
    env = OvercookedEnv("cramped_room", shaping=0.0)
    env.reset()
    total, sparse, shaped = one_soup(env)
    assert (total, sparse, shaped) == (20.0, 20.0, 17.0)  # the shaped reward is still reported, weighted by 0


def test_own_shaping_credits_the_player_who_earned_it() -> None:
    env = OvercookedEnv("cramped_room", shaping=0.5, shared_shaping=False)
    env.reset()
    play(env, ONION_TO_POT[:-1])
    _, rewards, _, _, infos = env.step({"player_0": INTERACT, "player_1": STAY})
    assert rewards == {"player_0": 1.5, "player_1": 0.0}
    assert infos["player_1"]["shaped_reward"] == 0.0 and infos["player_0"]["shaped_reward"] == 3.0


def test_a_hidden_utility_rewards_a_seat_by_its_own_weighted_events_only() -> None:
    weights = {"onion_pickup": 2.0, "potting_onion": -1.0, "dish_pickup": 0.25, "soup_delivery": 10.0}
    env = OvercookedEnv("cramped_room", shaping=1.0, hidden_utility={"player_0": weights, "player_1": {"onion_pickup": 7}})
    env.reset()
    partner_total = reported_shaping = 0.0
    events: list[str] = []
    for moves in (ONION_TO_POT, AGAIN, AGAIN, FETCH_DISH):
        for move in moves:
            _, rewards, _, _, infos = env.step({"player_0": move, "player_1": STAY})
            partner_total += rewards["player_1"]
            reported_shaping += infos["player_0"]["shaped_reward"]
            events += infos["player_0"]["events"]
            assert infos["player_1"]["events"] == ()
    # Each seat's infos name the events it caused.
    assert events.count("onion_pickup") == events.count("potting_onion") == 3 and "dish_pickup" in events
    # Player_0 picked 3 onions (2 each), potted 3 (-1 each), took a dish (0.25); player_1 caused nothing.
    total = play(env, [STAY] * env.state.objects[(2, 0)].cook_time_remaining + SERVE)[0]
    assert partner_total == 0.0
    assert total == 10.0  # picking the soup up is no weighted event; delivering it is
    assert reported_shaping == 3 * 3 + 3  # the game's rewards are still reported as they were


def test_a_hidden_utility_over_the_whole_soup_counts_each_event_once() -> None:
    weights = {"onion_pickup": 2.0, "potting_onion": -1.0, "dish_pickup": 0.25, "soup_delivery": 10.0}
    env = OvercookedEnv("cramped_room", hidden_utility={"player_0": weights})
    env.reset()
    assert one_soup(env)[0] == 3 * 2.0 - 3 * 1.0 + 0.25 + 10.0


@pytest.mark.parametrize(
    ("hidden", "match"),
    [
        ({"player_9": {"onion_pickup": 1}}, "unknown seat 'player_9'"),
        ({"player_0": {"onion_eaten": 1}}, "unknown event 'onion_eaten'"),
        ({"player_0": {"onion_pickup": float("nan")}}, r"\['onion_pickup'\] must be a finite number"),
        ({"player_0": {}}, "non-empty"),
        ([1, 2], "must map seats"),
    ],
)
def test_a_bad_hidden_utility_names_the_seat_or_event(hidden: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        OvercookedEnv("cramped_room", hidden_utility=hidden)


def test_set_shaping_changes_the_factor_and_rejects_bad_values() -> None:
    env = OvercookedEnv("cramped_room", shaping=1.0)
    env.set_shaping(0.25)
    env.reset()
    play(env, ONION_TO_POT[:-1])
    _, rewards, _, _, infos = env.step({"player_0": INTERACT, "player_1": STAY})
    assert rewards["player_0"] == rewards["player_1"] == 0.75 and infos["player_0"]["shaping"] == 0.25
    for bad in (-1.0, float("nan"), "1", True):
        with pytest.raises(ValueError, match="shaping must be"):
            env.set_shaping(bad)


def test_the_annealing_schedule_known_values() -> None:
    assert shaping_factor(0, 1000) == 1.0
    assert shaping_factor(250, 1000) == 0.75
    assert shaping_factor(1000, 1000) == 0.0
    assert shaping_factor(5000, 1000) == 0.0  # stays at the end value
    assert shaping_factor(500, 1000, start=2.0, end=1.0) == 1.5
    with pytest.raises(ValueError, match="shaping_horizon"):
        shaping_factor(0, 0)


def test_the_env_anneals_by_its_own_steps_across_episodes() -> None:
    env = OvercookedEnv("cramped_room", horizon=10, shaping=1.0, shaping_horizon=40)
    factors = []
    for _ in range(3):
        env.reset()
        while env.agents:
            _, _, _, _, infos = env.step({"player_0": STAY, "player_1": STAY})
            factors.append(infos["player_0"]["shaping"])
    assert factors[0] == 1.0 and factors[10] == 0.75 and factors[20] == 0.5 and factors[29] == pytest.approx(0.275)


def test_horizon_truncates_and_the_episode_then_refuses_steps() -> None:
    env = OvercookedEnv("cramped_room", horizon=5)
    env.reset()
    for step in range(5):
        _, _, terms, truncs, _ = env.step({"player_0": STAY, "player_1": STAY})
        assert not any(terms.values()) and all(truncs.values()) == (step == 4)
    assert env.agents == [] and env.state.timestep == 5
    with pytest.raises(ValueError, match="after the episode ended"):
        env.step({"player_0": STAY, "player_1": STAY})


def test_reset_from_a_given_state_honours_its_timestep_and_env_state_follows_the_mdp() -> None:
    mdp = OvercookedGridworld.from_layout_name("cramped_room", old_dynamics=True)
    start = OvercookedState(
        [
            PlayerState((2, 1), Direction.NORTH, SoupState.get_soup((2, 1), num_onions=3, finished=True)),
            PlayerState((3, 2), Direction.SOUTH),
        ],
        {},
        all_orders=[{"ingredients": ["onion"] * 3}],
        timestep=397,
    )
    env = OvercookedEnv("cramped_room", horizon=400)
    env.reset(options={"state": start})
    assert env.state == start and env.state is not start
    joint = {"player_0": SOUTH, "player_1": STAY}
    expected, _ = mdp.get_state_transition(start, (ACTIONS[SOUTH], ACTIONS[STAY]))
    _, _, _, truncs, _ = env.step(joint)
    assert env.state == expected and not any(truncs.values())
    env.step(joint)
    _, _, _, truncs, _ = env.step(joint)
    assert env.state.timestep == 400 and all(truncs.values())  # three steps from 397 reach the horizon
    assert start.timestep == 397  # the caller's state is untouched


def test_a_held_soup_delivered_from_a_given_state_scores_20() -> None:
    env = OvercookedEnv("cramped_room")  # first: building the MDP configures the recipes a cooked soup needs
    soup = SoupState.get_soup((3, 2), num_onions=3, finished=True)
    start = OvercookedState([PlayerState((1, 1), Direction.NORTH), PlayerState((3, 2), Direction.SOUTH, soup)], {}, timestep=0)
    env.reset(options={"state": start})
    _, rewards, _, _, infos = env.step({"player_0": STAY, "player_1": INTERACT})
    assert rewards == {"player_0": 20.0, "player_1": 20.0}
    assert infos["player_0"]["sparse_reward"] == 20.0 and env.state.players[1].held_object is None


def test_bad_states_and_actions_get_one_clear_error() -> None:
    env = OvercookedEnv("cramped_room", horizon=400)
    with pytest.raises(ValueError, match="must be an OvercookedState"):
        env.reset(options={"state": {"players": []}})
    on_counter = OvercookedState([PlayerState((0, 0), Direction.NORTH), PlayerState((3, 1), Direction.NORTH)], {})
    with pytest.raises(ValueError, match="not a valid state of layout 'cramped_room'"):
        env.reset(options={"state": on_counter})
    late = OvercookedState([PlayerState((1, 2), Direction.NORTH), PlayerState((3, 1), Direction.NORTH)], {}, timestep=400)
    with pytest.raises(ValueError, match="timestep 400"):
        env.reset(options={"state": late})
    env.reset()
    with pytest.raises(ValueError, match="no action for player_1"):
        env.step({"player_0": STAY})
    with pytest.raises(ValueError, match=r"action for player_0 must be an integer in \[0, 6\)"):
        env.step({"player_0": 6, "player_1": STAY})


def test_bad_layout_and_settings_name_what_is_wrong() -> None:
    with pytest.raises(
        ValueError, match="unknown Overcooked layout 'kitchen'; known layouts: cramped_room, asymmetric_advantages"
    ):
        OvercookedEnv("kitchen")
    with pytest.raises(ValueError, match="has 1 players"):
        OvercookedEnv("cramped_room_single")
    with pytest.raises(ValueError, match="cannot run with the 2019 dynamics"):
        OvercookedEnv("cramped_room_tomato")
    with pytest.raises(ValueError, match="horizon must be a positive integer"):
        OvercookedEnv(horizon=0)
    with pytest.raises(ValueError, match="unknown config key"):
        envs.make("overcooked", layuot="cramped_room")
    assert layouts()[:5] == CLASSIC_LAYOUTS and "random0" in layouts()


def test_layouts_with_other_recipes_share_a_process() -> None:
    # tutorial_0's soups cook for 45 ticks; the package configures recipes globally when an MDP is built.
    room, tutorial = OvercookedEnv("cramped_room"), OvercookedEnv("tutorial_0")
    soup = SoupState.get_soup((2, 0), num_onions=3, cooking_tick=0)
    start = OvercookedState([PlayerState((1, 2), Direction.NORTH), PlayerState((3, 1), Direction.NORTH)], {(2, 0): soup})
    room.reset(options={"state": start})
    tutorial.reset()
    play(room, [STAY] * 20)
    assert room.state.objects[(2, 0)].is_ready  # 20 ticks, not tutorial_0's 45


def test_the_record_is_registered_with_laptop_defaults() -> None:
    record = envs.game("overcooked")
    assert record.env is OvercookedEnv and record.title == "Overcooked-AI" and record.oracle is None
    assert record.training_defaults().hidden == 64


def test_rllib_sees_520_floats_and_six_legal_actions_per_seat() -> None:
    env = PettingZooMultiAgentEnv(envs.make("overcooked"))
    check_multiagent_environments(env)
    obs, _ = env.reset(seed=0)
    assert obs["player_0"]["observations"].shape == (520,) and obs["player_1"]["action_mask"].tolist() == [1.0] * 6


def test_without_the_extra_the_name_says_how_to_install_it() -> None:
    hide = (
        "import importlib.util; real = importlib.util.find_spec; "
        "importlib.util.find_spec = lambda name, *a: None if name == 'overcooked' else real(name, *a); "
        "from rllib_conv import envs\n"
        "try:\n    envs.game('overcooked')\nexcept ValueError as exc:\n    print(exc)\n"
        "print('overcooked' in envs.names())"
    )
    out = subprocess.run([sys.executable, "-c", hide], capture_output=True, text=True, check=True).stdout
    assert "pip install 'rllib-conv[overcooked]'" in out and out.strip().endswith("False")


def test_scores_are_measured_on_soups_alone_whatever_the_training_shaping() -> None:
    # Every measured score (evaluation, adaptation curves, pair, crossplay) builds its env through make_scored.
    scored = envs.make_scored("overcooked", layout="cramped_room", shaping=1.0, shaping_horizon=1000)
    assert scored.shaping_now() == 0.0 and scored.layout == "cramped_room"
    assert envs.make("overcooked", layout="cramped_room", shaping=1.0).shaping_now() == 1.0
    assert (envs.make_scored("bandit", symmetric=2).prizes == envs.make("bandit", symmetric=2).prizes).all()
