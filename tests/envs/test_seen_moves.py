"""The partner's moves as the ego's seat sees them: its own last observation and move, then the partner's action."""

from __future__ import annotations

import numpy as np

from rllib_conv import envs
from rllib_conv.envs.blocks.best_response import BlocksBestResponse
from rllib_conv.envs.replicated_game import ReplicatedGame, replica_agent
from rllib_conv.envs.rllib_adapter import RLLIB_OBS_KEY, PettingZooMultiAgentEnv
from rllib_conv.envs.seen_moves import SeenMoves


def test_nothing_is_kept_until_asked_and_a_partner_moving_before_the_ego_saw_anything_is_skipped() -> None:
    env = PettingZooMultiAgentEnv(envs.make("bandit"))
    env.reset(seed=0)
    env.step({"player_0": 1, "player_1": 2})
    assert env.take_seen_moves() is None
    seen = SeenMoves("player_0")
    seen.moved("player_1", 3)
    seen.saw("player_1", np.ones(2))  # the partner's observation is never kept
    seen.moved("player_1", 4)
    assert seen.take() is None


def test_bandit_each_partner_pull_is_kept_with_the_egos_context_of_the_same_step() -> None:
    env, rng, expected = PettingZooMultiAgentEnv(envs.make("bandit")), np.random.default_rng(0), []
    env.record_seen_moves("player_0")
    for episode in range(20):
        obs, _ = env.reset(seed=episode)
        ego, partner = int(rng.integers(8)), int(rng.integers(8))
        expected.append((obs["player_0"][RLLIB_OBS_KEY], ego, partner))
        env.step({"player_1": partner, "player_0": ego})  # the dict's order does not matter
    observations, ego_moves, moves = env.take_seen_moves()
    assert np.array_equal(observations, np.stack([e[0] for e in expected]))
    assert ego_moves.tolist() == [e[1] for e in expected] and moves.tolist() == [e[2] for e in expected]
    assert env.take_seen_moves() is None  # taken


def test_blocks_the_partners_situation_follows_from_the_egos_observation_and_move_by_the_rules() -> None:
    # What the ego's seat records, mapped through the planner's rules, is the observation P2 actually acted on.
    env, rng, planner = PettingZooMultiAgentEnv(envs.make("blocks")), np.random.default_rng(1), BlocksBestResponse()
    situations, _ = planner.situations()
    env.record_seen_moves("player_0")
    truth = []
    for episode in range(30):
        env.reset(seed=episode)
        while env.env.agents:
            agent = env.env.agent_selection
            if agent == "player_1":
                truth.append(env.env.observe(agent)["observation"])
            env.step({agent: int(rng.integers(6))})
    observations, ego_moves, moves = env.take_seen_moves()
    assert len(moves) == len(truth) == 30 * 3
    for observation, ego_move, p2_view in zip(observations, ego_moves, truth):
        assert np.array_equal(situations[planner.follows(observation, int(ego_move))], p2_view)


def test_a_replicated_game_keeps_each_copys_moves_apart() -> None:
    game = ReplicatedGame({"game": "bandit", "replica_seeds": [0, 1]})
    game.record_seen_moves(["player_0", "player_0"])
    game.reset(seed=0)
    game.step({replica_agent(a, r): (0 if a == "player_0" else 5 + r) for r in (0, 1) for a in ("player_0", "player_1")})
    first, second = game.take_seen_moves()
    assert first[2].tolist() == [5] and second[2].tolist() == [6]
