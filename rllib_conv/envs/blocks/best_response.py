"""Blocks: P1's exact best response to a P2 whose move probabilities are known in every observation.

P2 sees only the working grid and the move number, so its policy is a table over 21 grids
(red and blue each on one of 4 cells or off the grid, never on the same cell) x its 3
moves. Given that table, P1, who sees the goal, faces a 6-move decision problem solved
backwards over the grids, for each of the 12 goals at once.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.blocks.env import (
    BLUE,
    GOALS,
    HIDDEN,
    NUM_ACTIONS,
    NUM_CELLS,
    NUM_MOVES,
    RED,
    apply_move,
    block_cell,
    decode_observation,
    encode_observation,
    final_reward,
)

P2_MOVES = range(1, NUM_MOVES, 2)  # P1 moves at the even ones


def all_grids() -> list[np.ndarray]:
    """Every working grid a game can reach: red and blue each on a cell or off the grid, on different cells."""
    cells = [None, *range(NUM_CELLS)]
    grids = []
    for red in cells:
        for blue in cells:
            if red is not None and red == blue:
                continue
            grid = np.zeros(NUM_CELLS, dtype=np.int64)
            if red is not None:
                grid[red] = RED
            if blue is not None:
                grid[blue] = BLUE
            grids.append(grid)
    return grids


class BlocksPlan:
    """P1's planned move per (goal, working grid, move); `value[g]`: its expected score from the empty grid on goal `GOALS[g]`."""

    def __init__(self, moves: dict[int, np.ndarray], index: dict[tuple[int, ...], int], value: np.ndarray) -> None:
        self.moves, self.index, self.value = moves, index, value

    def act(self, observation: np.ndarray) -> int | None:
        seen = decode_observation(observation)
        if HIDDEN in seen["goal"] or seen["move"] not in self.moves:
            return None  # not P1's observation, or not its turn
        goal = GOALS.index((block_cell(seen["goal"], RED), block_cell(seen["goal"], BLUE)))
        return int(self.moves[seen["move"]][goal, self.index[tuple(seen["grid"])]])


class BlocksBestResponse:
    """Plans P1 (`player_0`) against P2 move probabilities given per P2 observation (`situations`: its 3 moves x 21 grids)."""

    def __init__(self, new_task: bool = False) -> None:
        self.grids = all_grids()
        self.index = {tuple(g): i for i, g in enumerate(self.grids)}
        # next_grid[colour][i, a]: the grid index after the owner of `colour` plays a on grid i.
        self.next_grid = {
            c: np.array([[self.index[tuple(apply_move(g, c, a))] for a in range(NUM_ACTIONS)] for g in self.grids])
            for c in (RED, BLUE)
        }
        hidden = np.full(NUM_CELLS, HIDDEN)
        self._situations = np.stack([encode_observation(hidden, g, m, sees_goal=False) for m in P2_MOVES for g in self.grids])
        self.rewards = np.array([[final_reward(goal, g, new_task) for g in self.grids] for goal in GOALS])  # [12 goals, grids]

    def situations(self) -> tuple[np.ndarray, np.ndarray]:
        return self._situations, np.ones((len(self._situations), NUM_ACTIONS), dtype=np.int8)

    def follows(self, observation: np.ndarray, action: int) -> int | None:
        seen = decode_observation(observation)
        if HIDDEN in seen["goal"] or seen["move"] + 1 not in P2_MOVES:
            return None  # not P1's observation, or no P2 move follows
        grid = apply_move(np.asarray(seen["grid"]), RED, int(action))
        return P2_MOVES.index(seen["move"] + 1) * len(self.grids) + self.index[tuple(grid)]

    def plan(self, predict: np.ndarray) -> BlocksPlan:
        predict = np.asarray(predict, dtype=np.float64).reshape(len(P2_MOVES), len(self.grids), NUM_ACTIONS)
        value, moves = self.rewards, {}
        for move in reversed(range(NUM_MOVES)):
            if move in P2_MOVES:
                value = (predict[move // 2] * value[:, self.next_grid[BLUE]]).sum(axis=-1)
            else:
                after = value[:, self.next_grid[RED]]  # [goals, grids, actions]
                moves[move] = after.argmax(axis=-1)
                value = after.max(axis=-1)
        return BlocksPlan(moves, self.index, value[:, self.index[(0,) * NUM_CELLS]])


def blocks_best_response(env_config: dict[str, Any], ego_agent: str) -> BlocksBestResponse | None:
    """The planner for an ego playing P1; None for P2 (it would need to infer the hidden goal)."""
    return BlocksBestResponse(bool(env_config.get("new_task", False))) if ego_agent == "player_0" else None


def blocks_best_response_return(partner: Any, env_config: dict[str, Any], ego_agent: str) -> float | None:
    """P1's best response's expected score against the P2 `partner`, goals uniform.

    None for an ego playing P2 (no planner), and for a partner that cannot say what it draws
    from or learns from P1's moves within an episode (its moves then depend on more than its
    observation, which the plan assumes).
    """
    planner = blocks_best_response(env_config, ego_agent)
    if planner is None or getattr(partner, "learns_in_play", False):
        return None
    situations, masks = planner.situations()
    try:
        predict = partner.action_probs(situations, masks)
    except ValueError:  # a partner that does not say what its actions are drawn from
        return None
    return float(planner.plan(predict).value.mean())
