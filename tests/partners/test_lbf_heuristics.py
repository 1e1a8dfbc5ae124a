"""LBF's heuristic partners H1-H4: the food each rule picks on hand-built states, its moves, and the package's own code."""

from __future__ import annotations

import random
from pathlib import Path

import lbforaging
import numpy as np
import pytest
from lbforaging.foraging.environment import Action

from rllib_conv import envs, partners
from rllib_conv.envs.lbf import EAST, LOAD, NONE, NORTH, SOUTH, WEST, SeenState, read_observation
from rllib_conv.partners.lbf import RULES, LBFHeuristic, heuristic_probs, heuristic_target

ALL_LEGAL = np.ones(6, dtype=np.int8)


def vector(food: list[tuple[int, int, int]], players: list[tuple[int, int, int]], food_slots: int, seats: int) -> np.ndarray:
    """An observation vector: the food triples (reading order) and the players (itself first), unused slots (-1, -1, 0)."""
    empty = [(-1, -1, 0)]
    rows = food + empty * (food_slots - len(food)) + players + empty * (seats - len(players))
    return np.array(rows, dtype=np.float32).reshape(-1)


def seen_as(food: list[tuple[int, int, int]], players: list[tuple[int, int, int]], food_slots: int, seats: int) -> SeenState:
    """What a seat sees in the observation `vector(...)`."""
    return read_observation(vector(food, players, food_slots, seats), food_slots, seats)


# Me at (4, 1), level 1; the others at (0, 6) and (2, 7), level 1: the centre is rint((2, 4.67)) = (2, 5), levels sum to 3.
PLAYERS = [(4, 1, 1), (0, 6, 1), (2, 7, 1)]
FOOD = [(2, 4, 4), (3, 7, 3), (4, 3, 2), (7, 1, 1)]  # reading order
#        to me:   13        37        4         9      -> H1: (4, 3);  level <= 1: H3: (7, 1)
#    to centre:    1         5        8        41      -> H2: (2, 4);  level <= 3: H4: (3, 7)
STATE = seen_as(FOOD, PLAYERS, 4, 3)
EXPECTED = {"H1": ((4, 3), EAST), "H2": ((2, 4), NORTH), "H3": ((7, 1), SOUTH), "H4": ((3, 7), NORTH)}


@pytest.mark.parametrize("rule", RULES)
def test_each_rule_picks_its_food_and_steps_toward_it(rule: str) -> None:
    target, move = EXPECTED[rule]
    assert heuristic_target(STATE, rule) == target
    assert heuristic_probs(STATE, rule, ALL_LEGAL).tolist() == np.eye(6)[move].tolist()


def test_next_to_its_food_it_loads_and_diagonally_it_steps() -> None:
    beside = seen_as([(4, 2, 1)], [(4, 1, 1), (0, 0, 1)], 1, 2)
    assert heuristic_probs(beside, "H1", ALL_LEGAL).argmax() == LOAD
    diagonal = seen_as([(3, 2, 1)], [(4, 1, 1), (0, 0, 1)], 1, 2)
    assert heuristic_probs(diagonal, "H1", ALL_LEGAL).argmax() == NORTH  # a row first, then a column


def test_a_blocked_step_tries_the_next_direction_then_moves_at_random() -> None:
    seen = seen_as([(2, 4, 1)], [(4, 1, 1), (0, 0, 1)], 1, 2)  # north-east of me
    no_north = np.array([1, 0, 1, 1, 1, 0], dtype=np.int8)
    assert heuristic_probs(seen, "H1", no_north).argmax() == EAST
    only_west_south = np.array([1, 0, 1, 1, 0, 0], dtype=np.int8)  # neither way toward it: uniform over the legal
    assert np.allclose(heuristic_probs(seen, "H1", only_west_south), only_west_south / 3)


def test_with_no_food_it_can_take_every_legal_action_is_equally_likely() -> None:
    # H3 at level 1 sees only a level-2 food: nothing it can load alone.
    seen = seen_as([(2, 4, 2)], [(4, 1, 1), (0, 0, 1)], 1, 2)
    assert heuristic_target(seen, "H3") is None
    mask = np.array([1, 1, 0, 1, 1, 0], dtype=np.int8)
    assert heuristic_probs(seen, "H3", mask).tolist() == [0.25, 0.25, 0.0, 0.25, 0.25, 0.0]
    assert heuristic_target(seen, "H1") == (2, 4)


def test_a_tie_goes_to_the_first_food_in_reading_order() -> None:
    seen = seen_as([(2, 3, 1), (4, 5, 1)], [(3, 4, 1), (0, 0, 1)], 2, 2)  # both at distance 2
    assert heuristic_target(seen, "H1") == (2, 3)


def test_the_partner_kind_is_registered_seeded_and_refuses_bad_parameters() -> None:
    assert "lbf_heuristic" in partners.kinds()
    spec = {"name": "h4", "kind": "lbf_heuristic", "params": {"rule": "H4", "food": 4, "players": 3}}
    built = partners.partner_from_spec(spec)
    assert built.to_spec() == spec and built.act(vector(FOOD, PLAYERS, 4, 3), ALL_LEGAL) == NORTH
    # Random moves come from the partner's own generator: one seed, one sequence.
    nothing = vector([], PLAYERS, 4, 3)
    draws = []
    for _ in range(2):
        built.seed(5)
        draws.append([built.act(nothing, ALL_LEGAL) for _ in range(20)])
    assert draws[0] == draws[1] and len(set(draws[0])) > 1
    with pytest.raises(ValueError, match="rule must be one of"):
        LBFHeuristic("x", rule="H5")
    with pytest.raises(ValueError, match="food must be the env's food"):
        LBFHeuristic("x", food=0)
    # Built for the env's defaults (3 food, 3 players), it refuses another env's vector rather than misread it.
    assert LBFHeuristic("x").params() == {"rule": "H1", "food": 3, "players": 3}
    with pytest.raises(ValueError, match="21 numbers is not one of an env with food=3 and players=3"):
        LBFHeuristic("x").act(vector(FOOD, PLAYERS, 4, 3), ALL_LEGAL)


def _reference_agents() -> dict[str, type]:
    """lbforaging's own H1-H4 (`agents/agent.py`, `agents/heuristic_agent.py`), their imports given by hand.

    Importing `lbforaging.agents` fails (`from foraging.environment import Action`, and plotly for another agent),
    so the two files are run as they are installed, with those import lines left out.
    """
    namespace = {"__name__": "lbforaging_heuristics", "Action": Action}
    for name in ("agent.py", "heuristic_agent.py"):
        source = (Path(lbforaging.__file__).parent / "agents" / name).read_text()
        body = "\n".join(line for line in source.splitlines() if not line.startswith(("from lbforaging.agents", "from foraging")))
        exec(compile(body, name, "exec"), namespace)  # noqa: S102 - the installed package's own files
    return {rule: namespace[rule] for rule in RULES}


@pytest.mark.parametrize("sight", [None, 2])
def test_every_move_is_the_packages_own_heuristics(sight: int | None) -> None:
    # Four seats, one of each type, play 400 steps; at each step every seat's choice is checked against the
    # package's agent on the package's own observation: the same move where ours is scripted, a legal one where random.
    random.seed(0)
    env = envs.make("lbf", players=4, size=8, food=3, sight=sight)
    reference = _reference_agents()
    seats = [LBFHeuristic(rule, rule=rule, food=3, players=4) for rule in RULES]
    for i, seat in enumerate(seats):
        seat.seed(i)
    obs, _ = env.reset(seed=1)
    checked = scripted = 0
    for _ in range(400):
        actions = {}
        for agent, seat, player in zip(env.possible_agents, seats, env.forage.players):
            theirs = reference[seat.rule](player)._step(env.forage._make_obs(player)).value
            ours = heuristic_probs(read_observation(obs[agent]["observation"], 3, 4), seat.rule, obs[agent]["action_mask"])
            if ours.max() == 1.0:
                assert theirs == int(ours.argmax()), (seat.rule, env.forage._make_obs(player))
                scripted += 1
            else:
                assert ours[theirs] > 0
            checked += 1
            actions[agent] = seat.act(obs[agent]["observation"], obs[agent]["action_mask"])
        obs, *_ = env.step(actions)
        if not env.agents:
            obs, _ = env.reset()
    assert checked == 1600 and scripted > 800  # most moves are scripted ones


def test_actions_are_the_packages_indices() -> None:
    assert [NONE, NORTH, SOUTH, WEST, EAST, LOAD] == [a.value for a in Action]
