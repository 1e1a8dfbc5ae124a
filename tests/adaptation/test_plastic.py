"""PLASTIC (`head_init: plastic`, not in the paper): its Bayes update by hand, then on Level-Based Foraging's recorded moves."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv import envs
from rllib_conv.adaptation.plastic import Plastic
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv
from rllib_conv.envs.seat_views import seat_view
from rllib_conv.partners.base import Partner
from rllib_conv.partners.lbf import LBFHeuristic


class Fixed(Partner):
    """A partner type that plays `probs` whatever it observes."""

    kind = "fixed_test_type"

    def __init__(self, name: str, probs: list[float]) -> None:
        super().__init__(name)
        self.probs = np.asarray(probs, dtype=np.float64)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return int(np.argmax(self.probs))

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        return np.tile(self.probs, (len(observations), 1))

    def params(self) -> dict:
        return {"probs": self.probs.tolist()}


A, B = Fixed("A", [0.7, 0.2, 0.1]), Fixed("B", [0.2, 0.5, 0.3])


def identity(observation: np.ndarray, ego_move: int) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(observation), np.ones(3, dtype=np.int8)  # every move legal, the ego's view is the seat's


def seen(moves: list[int], seats: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    n = len(moves)
    return np.zeros((n, 2), dtype=np.float32), -np.ones(n, dtype=np.int64), np.array(moves), np.array(seats, dtype=object)


def test_one_seats_belief_is_bayes_rule_over_the_smoothed_types_by_hand() -> None:
    plastic = Plastic([A, B], {"p1": identity}, epsilon=0.1)
    assert plastic.seat_belief("p1") == pytest.approx([0.5, 0.5]) and plastic.team() == ("A",)  # no evidence: the first
    plastic.observe(*seen([0, 0, 1], ["p1"] * 3))
    a = (0.9 * np.array([0.7, 0.2, 0.1]) + 0.1 / 3)[[0, 0, 1]].prod()
    b = (0.9 * np.array([0.2, 0.5, 0.3]) + 0.1 / 3)[[0, 0, 1]].prod()
    assert plastic.seat_belief("p1") == pytest.approx([a / (a + b), b / (a + b)], abs=1e-12)
    assert plastic.team() == ("A",) and plastic.head_id() == "ego@A"
    plastic.observe(*seen([1, 2, 1, 2], ["p1"] * 4))  # evidence adds up: B now
    a2, b2 = (
        a * (0.9 * 0.2 + 0.1 / 3) ** 2 * (0.9 * 0.1 + 0.1 / 3) ** 2,
        b * (0.9 * 0.5 + 0.1 / 3) ** 2 * (0.9 * 0.3 + 0.1 / 3) ** 2,
    )
    assert plastic.seat_belief("p1") == pytest.approx([a2 / (a2 + b2), b2 / (a2 + b2)], abs=1e-12)
    assert plastic.team() == ("B",)


def test_each_seat_learns_from_its_own_moves_and_the_team_belief_is_their_product() -> None:
    plastic = Plastic([A, B], {"p1": identity, "p2": identity}, epsilon=0.1)
    plastic.observe(*seen([0, 1, 0, 1, 1], ["p1", "p2", "p1", "p2", "p2"]))
    p1, p2 = plastic.seat_belief("p1"), plastic.seat_belief("p2")
    alone = Plastic([A, B], {"p1": identity}, epsilon=0.1)
    alone.observe(*seen([0, 0], ["p1", "p1"]))
    assert p1 == pytest.approx(alone.seat_belief("p1"), abs=1e-12)  # p2's moves never reach p1's belief
    teams = plastic.team_belief()
    assert list(teams) == [("A", "A"), ("A", "B"), ("B", "A"), ("B", "B")]
    assert teams[("A", "B")] == pytest.approx(p1[0] * p2[1]) and sum(teams.values()) == pytest.approx(1.0)
    assert plastic.team() == max(teams, key=teams.get) == ("A", "B") and plastic.head_id() == "ego@A+B"


def test_a_move_the_rebuilt_mask_calls_illegal_is_still_evidence() -> None:
    # A view that (wrongly) masks action 2: the move is judged against the types, never given probability zero.
    plastic = Plastic([A, B], {"p1": lambda o, m: (np.asarray(o), np.array([1, 1, 0], dtype=np.int8))}, epsilon=0.1)
    plastic.observe(*seen([2, 2], ["p1", "p1"]))
    belief = plastic.seat_belief("p1")
    assert np.isfinite(belief).all() and belief[1] > belief[0]


def test_on_level_based_foraging_plastic_names_the_team_from_the_moves_the_egos_seat_records() -> None:
    pytest.importorskip("lbforaging")
    config, team = {"players": 3}, {"player_1": "H2", "player_2": "H1"}
    env, rng = PettingZooMultiAgentEnv(envs.make("lbf", **config)), np.random.default_rng(0)
    players = {agent: LBFHeuristic(rule, rule=rule) for agent, rule in team.items()}
    env.record_seen_moves("player_0")
    for episode in range(6):
        observations, _ = env.reset(seed=episode)
        while env.env.agents:
            actions = {"player_0": int(rng.choice(np.flatnonzero(observations["player_0"]["action_mask"])))}
            for agent, player in players.items():
                actions[agent] = player.act(observations[agent]["observations"], observations[agent]["action_mask"])
            observations, *_ = env.step(actions)
    views = {agent: seat_view("lbf", config, "player_0", agent) for agent in team}
    plastic = Plastic([LBFHeuristic("H1", rule="H1"), LBFHeuristic("H2", rule="H2")], views)
    plastic.observe(*env.take_seen_moves(seated=True))
    assert plastic.team() == ("H2", "H1") and plastic.head_id() == "ego@H2+H1"
    assert min(plastic.seat_belief("player_1")[1], plastic.seat_belief("player_2")[0]) > 0.99
