"""Blocks' oracle for P1 (the ego), and which of its moves are one move.

The hand rule of the paper's hand-designed partners. Move 0: put red on any cell other
than the blue goal (every such cell is some derangement partner's signal for the blue
goal, each for 3 of the 9). Moves 2 and 4: put red on its target (the red goal; on the
new task, a goal-empty cell) unless it is there, in which case passing or re-placing it
are the (equivalent) optimal moves. Re-placing red where it is, or removing it when it is
off the grid, is a pass (`blocks_canonical`).
"""

from __future__ import annotations

import numpy as np

from rllib_conv.envs.blocks.env import BLUE, NUM_ACTIONS, NUM_CELLS, PASS, RED, REMOVE
from rllib_conv.envs.game import OracleFn


def _blocks_grid(obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decode a batch of P1 observations into goal [B, 4], working grid [B, 4] and move [B]."""
    obs = np.asarray(obs)
    goal = obs[:, : NUM_CELLS * 4].reshape(-1, NUM_CELLS, 4).argmax(axis=2)
    grid = obs[:, NUM_CELLS * 4 : NUM_CELLS * 7].reshape(-1, NUM_CELLS, 3).argmax(axis=2)
    return goal, grid, obs[:, NUM_CELLS * 7 :].argmax(axis=1)


def blocks_canonical(obs: np.ndarray) -> np.ndarray:
    """P1's moves that change nothing are one move: placing red where it is, or removing it when off the grid, is a pass."""
    _, grid, _ = _blocks_grid(obs)
    canon = np.tile(np.arange(NUM_ACTIONS), (len(grid), 1))
    red_on = grid == RED
    canon[:, :NUM_CELLS][red_on] = PASS
    canon[~red_on.any(axis=1), REMOVE] = PASS
    return canon


def blocks_oracle(new_task: bool = False, render_mode: str | None = None) -> OracleFn:
    """Hand-rule oracle of blocks for P1 (see the module docstring)."""

    def oracle(obs: np.ndarray) -> np.ndarray:
        goal, grid, move = _blocks_grid(obs)
        target = (goal == 0) if new_task else (goal == RED)  # [B, cells]
        red_on = grid == RED
        out = np.zeros((len(obs), NUM_ACTIONS), dtype=np.float32)
        first = move == 0
        out[first, :NUM_CELLS] = goal[first] != BLUE
        later = ~first
        done = (red_on & target).any(axis=1) & later
        out[done, PASS] = 1.0
        out[done, :NUM_CELLS] = red_on[done]
        todo = later & ~done
        out[todo, :NUM_CELLS] = target[todo]
        return out

    return oracle
