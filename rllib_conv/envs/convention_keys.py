"""Convention keys: which situations of a game carry a convention of their own.

A game registers `key(observation) -> int` when its coordination problems come in
separate situations that both seats can name from their own observation, and a partner's
choice in one says nothing about its choice in another. The bandit is such a game: each
context is its own coordination problem (the context is both seats' one-hot observation).
The convention-posterior adapter (`rllib_conv.training.convention_posterior`) then also
considers partners that recombine known conventions situation by situation. Games without
a key (blocks, Hanabi: one strategy links all of a partner's moves) are judged whole.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

KeyFn = Callable[[np.ndarray], int]
_KEYS: dict[str, KeyFn] = {}


def register_convention_key(env_name: str, key: KeyFn) -> None:
    """Register `key(observation vector) -> int` for the game `env_name` (either seat's observation)."""
    _KEYS[env_name] = key


def convention_key(env_name: str) -> KeyFn | None:
    """The convention key of `env_name`, or None if its conventions are judged whole."""
    return _KEYS.get(env_name)


def bandit_context(observation: np.ndarray) -> int:
    """The bandit's context: the index of its one-hot observation."""
    return int(np.asarray(observation).argmax())


register_convention_key("bandit", bandit_context)
