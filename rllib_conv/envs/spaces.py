"""Observation-space and action-check conventions shared by the built-in games.

Every built-in game observes `{"observation": float32 vector, "action_mask": int8
vector}` (PettingZoo's classic-env convention), even when every action is legal,
so that one policy network and one RLlib adapter serve all games.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

OBS_KEY = "observation"
MASK_KEY = "action_mask"


def masked_observation_space(obs_dim: int, num_actions: int, high: float = 1.0) -> spaces.Dict:
    """Return the Dict space `{observation: Box(obs_dim), action_mask: Box(num_actions)}`."""
    return spaces.Dict(
        {
            OBS_KEY: spaces.Box(0.0, high, shape=(obs_dim,), dtype=np.float32),
            MASK_KEY: spaces.Box(0, 1, shape=(num_actions,), dtype=np.int8),
        }
    )


def validate_action(action: Any, mask: np.ndarray, *, env: str, agent: str) -> int:
    """Return `action` as an int if it is a legal move under `mask`, else raise ValueError.

    An illegal or out-of-range action never silently becomes another move.
    """
    num_actions = len(mask)
    try:
        a = int(action)
    except (TypeError, ValueError):
        raise ValueError(f"{env}: action for {agent} must be an integer in [0, {num_actions}), got {action!r}") from None
    if a != action or not 0 <= a < num_actions:
        raise ValueError(f"{env}: action for {agent} must be an integer in [0, {num_actions}), got {action!r}")
    if not mask[a]:
        legal = np.flatnonzero(mask).tolist()
        raise ValueError(f"{env}: action {a} is not legal for {agent} now; legal actions: {legal}")
    return a


def check_choice(name: str, value: Any, allowed: list | range) -> None:
    """Raise ValueError naming `name` unless `value` is one of `allowed`."""
    if value not in allowed:
        shown = f"{allowed.start}..{allowed.stop - 1}" if isinstance(allowed, range) else allowed
        raise ValueError(f"{name} must be one of {shown}, got {value!r}")
