"""`ReplicatedGame`: K copies of a game as one RLlib env, each copy exactly the game its replica would play alone."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv.common.seeds import game_seed
from rllib_conv.envs.replicated_game import ReplicatedGame, replicated_env_config, split_agent


def replicated(game: str, seeds: list[int], **game_config) -> ReplicatedGame:
    return ReplicatedGame(replicated_env_config(game, game_config, seeds, base_seed=0))


def first_mover_actions(obs: dict) -> dict:
    """The first legal action of every agent asked to move."""
    return {agent: int(np.flatnonzero(o["action_mask"])[0]) for agent, o in obs.items()}


def test_agents_and_spaces_carry_their_replica() -> None:
    env = replicated("bandit", [4, 9], symmetric=2)
    assert env.possible_agents == ["player_0#0", "player_1#0", "player_0#1", "player_1#1"]
    assert split_agent("player_1#1") == ("player_1", 1)
    obs, infos = env.reset(seed=0)
    assert set(obs) == set(env.possible_agents) and infos == {}
    for agent, o in obs.items():
        assert env.observation_spaces[agent].contains(o)


@pytest.mark.parametrize(("game", "config"), [("bandit", {"symmetric": 2}), ("blocks", {})])
def test_a_copy_plays_the_games_its_replica_would_alone(game: str, config: dict) -> None:
    """Replica 1 of [5, 3, 7] sees the episodes of a lone replica with seed 3: same observations, rewards and ends."""
    packed, alone = replicated(game, [5, 3, 7], **config), replicated(game, [3], **config)
    for episode in range(3):
        obs_p, _ = packed.reset(seed=10 + episode)
        obs_a, _ = alone.reset(seed=10 + episode)
        done = False
        while not done:
            mine = {split_agent(a)[0]: o for a, o in obs_p.items() if split_agent(a)[1] == 1}
            assert mine.keys() == {split_agent(a)[0] for a in obs_a}
            for agent, o in obs_a.items():
                np.testing.assert_array_equal(mine[split_agent(agent)[0]]["observations"], o["observations"])
            obs_p, rew_p, term_p, trunc_p, _ = packed.step(first_mover_actions(obs_p))
            obs_a, rew_a, term_a, trunc_a, _ = alone.step(first_mover_actions(obs_a))
            assert {split_agent(a)[0]: r for a, r in rew_p.items() if split_agent(a)[1] == 1} == {
                split_agent(a)[0]: r for a, r in rew_a.items()
            }
            done = term_a["__all__"] or trunc_a["__all__"]
            copy_done = all(
                term_p.get(f"{split_agent(a)[0]}#1", False) or trunc_p.get(f"{split_agent(a)[0]}#1", False)
                for a in alone.possible_agents
            )
            assert copy_done == done


def test_other_replicas_see_other_games() -> None:
    env = replicated("bandit", [5, 3, 7], symmetric=2)
    contexts = {r: [] for r in range(3)}
    for episode in range(20):
        obs, _ = env.reset(seed=episode)
        for r in range(3):
            contexts[r].append(int(np.argmax(obs[f"player_0#{r}"]["observations"])))
        env.step(first_mover_actions(obs))
    assert contexts[0] != contexts[1] != contexts[2]
    assert game_seed(3, 4) != game_seed(4, 3)


def test_an_episode_ends_when_every_copy_has_ended() -> None:
    env = replicated("blocks", [0, 1])
    obs, _ = env.reset(seed=0)
    steps = 0
    while True:
        assert {split_agent(a)[1] for a in obs} <= {0, 1} and len({split_agent(a)[1] for a in obs}) == len(
            obs
        )  # one mover per copy
        obs, _, terms, truncs, _ = env.step(first_mover_actions(obs))
        steps += 1
        if terms["__all__"] or truncs["__all__"]:
            break
    assert steps == 6  # blocks: six moves, the same for every copy


def test_a_config_without_a_game_is_refused() -> None:
    with pytest.raises(ValueError, match="needs env_config\\['game'\\]"):
        ReplicatedGame({"replica_seeds": [0]})


@pytest.mark.parametrize("game", ["blocks", "hanabi"])
def test_each_copy_counts_its_own_moves(game: str) -> None:
    # What a replica played, exactly: the steps in which its copy had a mover. RLlib's per-module
    # counts are counts of observations (each agent's final one included: 7 per 6-move blocks
    # episode), and in Hanabi a finished copy waits for the longest one.
    env = replicated(game, [0, 1, 2])
    expected = [0, 0, 0]
    for episode in range(2):
        obs, _ = env.reset(seed=episode)
        done = False
        while not done:
            for r in {split_agent(a)[1] for a in obs}:
                expected[r] += 1
            obs, _, terms, truncs, _ = env.step(first_mover_actions(obs))
            done = terms["__all__"] or truncs["__all__"]
            obs = {a: o for a, o in obs.items() if not (terms.get(a) or truncs.get(a))}  # final observations ask for no move
    assert env.take_moves() == expected and env.take_moves() == [0, 0, 0]
    if game == "blocks":
        assert expected == [12, 12, 12]
