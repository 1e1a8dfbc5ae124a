"""Convention keys: which situations of a game carry a convention of their own.

A game registers `key(observation) -> int` when its coordination problems come in
separate situations that a partner can tell apart from its own observation, and a
partner's choice in one says nothing about its choice in another. The convention-posterior
adapter (`rllib_conv.training.convention_posterior`) then also considers partners that
recombine known conventions situation by situation. Games without a key (Hanabi, whose
observations rarely repeat) judge each move on its own there.

- Bandit: each context is its own coordination problem (the context is both seats'
  one-hot observation), so the ego answers a seen context with the convention it follows.
- Blocks: a partner's observation is all it acts on (the goal hidden from P2, the working
  grid, the move number), so each distinct observation is a situation. The ego's own
  observations are other situations: it answers by planning against the partner's
  predicted moves (`envs.best_response`), not by looking a situation up.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rllib_conv.envs.blocks import NUM_CELLS, NUM_MOVES, decode_observation

KeyFn = Callable[[np.ndarray], int]
_KEYS: dict[str, KeyFn] = {}


def register_convention_key(env_name: str, key: KeyFn) -> None:
    """Register `key(observation vector) -> int` for the game `env_name` (any seat's observation)."""
    _KEYS[env_name] = key


def convention_key(env_name: str) -> KeyFn | None:
    """The convention key of `env_name`, or None if each move is its own situation."""
    return _KEYS.get(env_name)


def bandit_context(observation: np.ndarray) -> int:
    """The bandit's context: the index of its one-hot observation."""
    return int(np.asarray(observation).argmax())


def blocks_observation(observation: np.ndarray) -> int:
    """Blocks: the observation as one number (the goal as seen, the working grid, the move)."""
    seen = decode_observation(observation)
    goal = int(np.dot(seen["goal"], 4 ** np.arange(NUM_CELLS)))
    grid = int(np.dot(seen["grid"], 3 ** np.arange(NUM_CELLS)))
    return (goal * 3**NUM_CELLS + grid) * (NUM_MOVES + 1) + seen["move"]


register_convention_key("bandit", bandit_context)
register_convention_key("blocks", blocks_observation)
