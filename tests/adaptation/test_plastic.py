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


class FirstLegal(Partner):
    """A stand-in for one of the trained ego's heads: plays the first legal action and counts its moves."""

    kind = "first_legal_test_head"

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.moves = 0

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        self.moves += 1
        return int(np.flatnonzero(action_mask)[0])

    def params(self) -> dict:
        return {}


class Heads:
    """A stand-in for a trained ego: its head IDs (the player's heads are replaced before it plays)."""

    def head_ids(self) -> list[str]:
        return [f"ego@{a}+{b}" for a in ("H1", "H2") for b in ("H1", "H2")]


def test_the_player_updates_its_belief_within_the_episode_from_the_egos_view_and_starts_each_from_the_evidence() -> None:
    pytest.importorskip("lbforaging")
    from rllib_conv.partners.episodes import episode_stream

    config, seats = {"players": 3}, ("player_1", "player_2")
    views = {agent: seat_view("lbf", config, "player_0", agent) for agent in seats}
    plastic = Plastic([LBFHeuristic("H1", rule="H1"), LBFHeuristic("H2", rule="H2")], views)
    player = plastic.player(Heads())
    player.heads = {mid: FirstLegal(mid) for mid in player.heads}
    team = {"player_0": player, "player_1": LBFHeuristic("H2", rule="H2"), "player_2": LBFHeuristic("H1", rule="H1")}
    # On this field (seed 3) H1 and H2 go for different food in both seats early on (on some, e.g. seed 0, they agree).
    _, steps = next(episode_stream(envs.make("lbf", **config), team, seed=3))
    played = {mid: head.moves for mid, head in player.heads.items()}
    assert sum(played.values()) == steps and played["ego@H2+H1"] > 0.8 * steps  # found within a few moves of the episode
    assert player._live.team() == ("H2", "H1") and plastic.team() == ("H1", "H1")  # the evidence before it is untouched
    player.start_episode()
    assert player._live.team() == ("H1", "H1")
    # The partner's own observation, which play hands it, is never read: garbage there changes nothing.
    before = player._live.seat_belief("player_1")
    player.observe_other(np.full(18, np.nan), np.ones(6, dtype=np.int8), 1, "player_1")  # the ego has not acted yet
    assert np.array_equal(player._live.seat_belief("player_1"), before)
    observation = envs.make("lbf", **config).reset(seed=3)[0]["player_0"]["observation"]
    player.act(observation, np.ones(6, dtype=np.int8))
    player.observe_other(np.full(18, np.nan), np.ones(6, dtype=np.int8), 1, "player_1")
    reference = plastic.copy()
    reference.observe(observation[None], np.array([player._move]), np.array([1]), np.array(["player_1"], dtype=object))
    assert player._live.seat_belief("player_1") == pytest.approx(reference.seat_belief("player_1"), abs=1e-12)
