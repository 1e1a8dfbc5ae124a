"""The 2x2 block placing game: PettingZoo API, seeding, moves, hidden goal and rewards."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import api_test, seed_test

from rllib_conv import envs
from rllib_conv.envs.blocks import (
    BLUE,
    EMPTY,
    GOALS,
    HIDDEN,
    PASS,
    RED,
    REMOVE,
    decode_observation,
    final_reward,
)


def play(moves: list[int], goal: tuple[int, int] = (0, 3), new_task: bool = False):
    """Play `moves` (alternating P1, P2) from a reset with `goal` forced; return the env."""
    env = envs.make("blocks", new_task=new_task)
    env.reset(seed=0)
    env.goal = goal
    for a in moves:
        env.step(a)
    return env


@pytest.mark.parametrize("new_task", [False, True])
def test_pettingzoo_api_and_seed(new_task: bool) -> None:
    api_test(envs.make("blocks", new_task=new_task), num_cycles=60)
    seed_test(lambda: envs.make("blocks", new_task=new_task), num_cycles=60)


def test_twelve_goals_drawn_uniformly_from_the_seeded_rng() -> None:
    assert len(GOALS) == 12 == len(set(GOALS)) and all(r != b for r, b in GOALS)
    env = envs.make("blocks")
    env.reset(seed=5)
    goals = [env.goal for _ in range(1200) if env.reset() is None]
    env.reset(seed=5)
    again = [env.goal for _ in range(1200) if env.reset() is None]
    assert goals == again
    counts = np.array([goals.count(g) for g in GOALS])
    assert (abs(counts - 100) < 50).all(), counts


def test_place_moves_own_block_and_evicts_the_other() -> None:
    env = play([0])
    assert env.grid.tolist() == [RED, EMPTY, EMPTY, EMPTY]
    env.step(0)  # P2 puts blue on red's cell: red is evicted
    assert env.grid.tolist() == [BLUE, EMPTY, EMPTY, EMPTY]
    env.step(2)  # P1 places red again
    env.step(1)  # P2 moves blue: its old cell empties
    assert env.grid.tolist() == [EMPTY, BLUE, RED, EMPTY]


def test_remove_and_pass() -> None:
    env = play([3, 1, REMOVE])
    assert env.grid.tolist() == [EMPTY, BLUE, EMPTY, EMPTY]
    env.step(PASS)
    assert env.grid.tolist() == [EMPTY, BLUE, EMPTY, EMPTY]
    env.step(REMOVE)  # removing a block that is off the grid changes nothing
    assert env.grid.tolist() == [EMPTY, BLUE, EMPTY, EMPTY]


def test_only_p1_sees_the_goal() -> None:
    env = play([], goal=(2, 1))
    p1 = decode_observation(env.observe("player_0")["observation"])
    p2 = decode_observation(env.observe("player_1")["observation"])
    assert p1["goal"].tolist() == [EMPTY, BLUE, RED, EMPTY]
    assert p2["goal"].tolist() == [HIDDEN] * 4
    env.step(3)
    p2 = decode_observation(env.observe("player_1")["observation"])
    assert p2["grid"].tolist() == [EMPTY, EMPTY, EMPTY, RED] and p2["move"] == 1


@pytest.mark.parametrize(
    ("moves", "goal", "new_task", "expected"),
    [
        ([0, 3, PASS, PASS, PASS, PASS], (0, 3), False, 20.0),  # both right
        ([1, 3, PASS, PASS, 0, PASS], (0, 3), False, 20.0),  # red fixed on the last P1 move
        ([0, 2, PASS, PASS, PASS, PASS], (0, 3), False, 10.0),  # blue wrong
        ([0, 3, PASS, 0, PASS, PASS], (0, 3), False, 0.0),  # blue leaves its goal and evicts red
        ([REMOVE, PASS] * 3, (0, 3), False, 0.0),
        ([1, 3, PASS, PASS, PASS, PASS], (0, 3), True, 20.0),  # new task: red on a goal-empty cell
        ([0, 3, PASS, PASS, PASS, PASS], (0, 3), True, 10.0),  # new task: red on its old goal is wrong
        ([2, 3, PASS, PASS, PASS, PASS], (0, 3), True, 20.0),
    ],
)
def test_final_reward_by_hand(moves, goal, new_task, expected) -> None:
    env = play(moves[:-1], goal=goal, new_task=new_task)
    assert env._cumulative_rewards == {"player_0": 0.0, "player_1": 0.0}  # nothing before the end
    env.step(moves[-1])
    assert all(env.terminations.values())
    assert env.rewards == {"player_0": expected, "player_1": expected}
    assert final_reward(goal, env.grid, new_task) == expected
    for agent in env.agents:
        assert env.infos[agent]["score"] == expected


def test_six_alternating_moves_then_terminal() -> None:
    env = play([])
    order = []
    for agent in env.agent_iter():
        _, _, term, _, _ = env.last()
        if term:
            env.step(None)
            continue
        order.append(agent)
        env.step(PASS)
    assert order == ["player_0", "player_1"] * 3


@pytest.mark.parametrize("bad", [6, -1, 2.5, "1"])
def test_actions_outside_the_space_raise(bad) -> None:
    env = play([])
    with pytest.raises(ValueError, match="blocks: action for player_0"):
        env.step(bad)
    assert env.move == 0 and env.grid.tolist() == [0, 0, 0, 0]


def test_bad_config() -> None:
    with pytest.raises(ValueError, match="new_task must be a bool"):
        envs.make("blocks", new_task=1)
    with pytest.raises(
        ValueError, match=r"env 'blocks' got unknown config key\(s\) \['symmetric'\]; accepted: new_task, render_mode"
    ):
        envs.make("blocks", symmetric=2)
    with pytest.raises(ValueError, match="unknown env 'chess'; registered envs: bandit, blocks, hanabi"):
        envs.make("chess")
