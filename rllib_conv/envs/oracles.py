"""Optimal-action sets per game, for the `oracle` method and the marginal-distance metric.

An oracle maps a batch of the ego's observation vectors `[B, obs_dim]` to a 0/1 mask
`[B, num_actions]` of the actions that are optimal whatever the partner's convention;
the true marginal best response is uniform over that set.

- bandit: the arms with the highest prize in the observed context (exact).
- blocks (ego = P1): the hand rule of the paper's hand-designed partners. Move 0: put
  red on any cell other than the blue goal (every such cell is some derangement
  partner's signal for the blue goal, each for 3 of the 9). Moves 2 and 4: put red on
  its target (the red goal; on the new task, a goal-empty cell) unless it is there,
  in which case passing or re-placing it are the (equivalent) optimal moves.

Distributions are compared over distinct moves: `canonical_actions` merges actions that
have the same effect in a state (for blocks P1: re-placing red where it is, or removing it
when it is off the grid, is a pass), so a policy is not charged for picking one of two
identical moves.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from rllib_conv.envs.bandit import CollaborativeBanditEnv
from rllib_conv.envs.blocks import BLUE, NUM_ACTIONS, NUM_CELLS, PASS, RED, REMOVE

OracleFn = Callable[[np.ndarray], np.ndarray]
_ORACLES: dict[str, Callable[..., OracleFn]] = {}
# Per game: obs [B, d] -> [B, A] canonical action of each action (actions with the same effect
# in that state share one), so distributions are compared over distinct moves.
_CANONICAL: dict[str, Callable[[np.ndarray], np.ndarray]] = {}


def register_oracle(env_name: str, builder: Callable[..., OracleFn]) -> None:
    """Register `builder(**env_config) -> OracleFn` for the game `env_name`."""
    _ORACLES[env_name] = builder


def canonical_actions(env_name: str, obs: np.ndarray, num_actions: int) -> np.ndarray:
    """[B, A] index of the canonical action of each action (identity if the game declares none)."""
    if env_name in _CANONICAL:
        return _CANONICAL[env_name](obs)
    return np.tile(np.arange(num_actions), (len(obs), 1))


def has_oracle(env_name: str) -> bool:
    """Return whether `env_name` has an oracle (needed by the `oracle` method and marginals)."""
    return env_name in _ORACLES


def oracle_for(env_name: str, env_config: dict[str, Any]) -> OracleFn:
    """Return the optimal-action oracle of `env_name` with `env_config`; ValueError if there is none."""
    if env_name not in _ORACLES:
        raise ValueError(f"no optimal-action oracle for env {env_name!r}; games with one: {', '.join(sorted(_ORACLES))}")
    return _ORACLES[env_name](**env_config)


def bandit_oracle(**env_config: Any) -> OracleFn:
    """Exact oracle of the bandit: the highest-prize arms of the one-hot context."""
    env = CollaborativeBanditEnv(**env_config)
    optimal = (env.prizes == env.prizes.max(axis=1, keepdims=True)).astype(np.float32)
    return lambda obs: np.asarray(obs, dtype=np.float32) @ optimal


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


register_oracle("bandit", bandit_oracle)
register_oracle("blocks", blocks_oracle)
_CANONICAL["blocks"] = blocks_canonical
