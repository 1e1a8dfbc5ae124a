"""Blocks' exact expected return of two fixed policies: a sum over the 12 goals and every move, no sampling.

The game is 6 moves on a working grid of 21 reachable states (`best_response.all_grids`),
so the distribution over (goal, grid) is carried forward move by move: at P1's moves each
(goal, grid) is one observation (P1 sees the goal), at P2's one per grid (it does not). 504
P1 and 63 P2 observations in all, against 200 sampled episodes of 6 moves each.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from rllib_conv.envs.blocks.best_response import P2_MOVES, all_grids
from rllib_conv.envs.blocks.env import (
    BLUE,
    GOALS,
    HIDDEN,
    NUM_ACTIONS,
    NUM_CELLS,
    NUM_MOVES,
    RED,
    apply_move,
    encode_observation,
    final_reward,
)


def _goal_grid(goal: tuple[int, int]) -> np.ndarray:
    grid = np.zeros(NUM_CELLS, dtype=np.int64)
    grid[goal[0]], grid[goal[1]] = RED, BLUE
    return grid


@dataclass(frozen=True)
class _Tables:
    """What does not depend on the players, built once per task: observations, moves' effects, rewards."""

    p1_obs: dict[int, np.ndarray]  # P1's move -> [goals * grids, 35]
    p2_obs: dict[int, np.ndarray]  # P2's move -> [grids, 35]
    after: dict[int, np.ndarray]  # colour -> [grids, actions]: the grid index after the move
    start: int  # the empty grid's index
    rewards: np.ndarray  # [goals, grids]


@lru_cache(maxsize=2)
def _tables(new_task: bool) -> _Tables:
    grids = all_grids()
    index = {tuple(g): i for i, g in enumerate(grids)}
    hidden = np.full(NUM_CELLS, HIDDEN)
    return _Tables(
        p1_obs={
            m: np.stack([encode_observation(_goal_grid(goal), g, m, sees_goal=True) for goal in GOALS for g in grids])
            for m in range(0, NUM_MOVES, 2)
        },
        p2_obs={m: np.stack([encode_observation(hidden, g, m, sees_goal=False) for g in grids]) for m in P2_MOVES},
        after={
            c: np.array([[index[tuple(apply_move(g, c, a))] for a in range(NUM_ACTIONS)] for g in grids]) for c in (RED, BLUE)
        },
        start=index[(0,) * NUM_CELLS],
        rewards=np.array([[final_reward(goal, g, new_task) for g in grids] for goal in GOALS]),
    )


def blocks_exact_return(policies: dict[str, Any], env_config: dict[str, Any]) -> float | None:
    """The expected final score of `policies` (`player_0`: P1, `player_1`: P2), goals uniform; None if one cannot say.

    Each policy gives `action_probs(observations, masks)`. None when a policy cannot say what
    it draws from, or learns from the other's moves within an episode (its probabilities at
    a move then depend on the episode so far, not on the observation alone).
    """
    players = [policies["player_0"], policies["player_1"]]
    if any(getattr(p, "learns_in_play", False) for p in players):
        return None
    t = _tables(bool(env_config.get("new_task", False)))
    goals, grids = t.rewards.shape
    try:
        probs = {  # [goals, grids, actions] at every move; P2 does not see the goal
            **{m: players[0].action_probs(o, np.ones((len(o), NUM_ACTIONS), np.int8)) for m, o in t.p1_obs.items()},
            **{m: players[1].action_probs(o, np.ones((len(o), NUM_ACTIONS), np.int8)) for m, o in t.p2_obs.items()},
        }
    except ValueError:  # a policy that does not say what its actions are drawn from
        return None
    state = np.zeros((goals, grids))
    state[:, t.start] = 1.0 / goals
    for move in range(NUM_MOVES):
        p = np.broadcast_to(np.asarray(probs[move]).reshape(-1, grids, NUM_ACTIONS), (goals, grids, NUM_ACTIONS))
        after = t.after[BLUE if move in P2_MOVES else RED]
        nxt = np.zeros_like(state)
        for a in range(NUM_ACTIONS):
            np.add.at(nxt, (slice(None), after[:, a]), state * p[:, :, a])
        state = nxt
    return float((state * t.rewards).sum())
