"""Optimal-action sets per game, for the `oracle` method and the marginal-distance metric.

An oracle maps a batch of the ego's observation vectors `[B, obs_dim]` to a 0/1 mask
`[B, num_actions]` of the actions that are optimal whatever the partner's convention;
the true marginal best response is uniform over that set. A game declares its oracle in
its record (`GameRecord.oracle`; the bandit's and blocks' sit in their folders).

Distributions are compared over distinct moves: `canonical_actions` merges actions that
have the same effect in a state (`GameRecord.canonical`), so a policy is not charged for
picking one of two identical moves.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.game import OracleFn
from rllib_conv.envs.registry import game, games


def canonical_actions(env_name: str, obs: np.ndarray, num_actions: int) -> np.ndarray:
    """[B, A] index of the canonical action of each action (identity if the game declares none)."""
    canonical = game(env_name).canonical
    if canonical is not None:
        return canonical(obs)
    return np.tile(np.arange(num_actions), (len(obs), 1))


def has_oracle(env_name: str) -> bool:
    """Return whether `env_name` has an oracle (needed by the `oracle` method and marginals)."""
    return game(env_name).oracle is not None


def oracle_for(env_name: str, env_config: dict[str, Any]) -> OracleFn:
    """Return the optimal-action oracle of `env_name` with `env_config`; ValueError if there is none."""
    build = game(env_name).oracle
    if build is None:
        with_one = [g.name for g in games() if g.oracle is not None]
        raise ValueError(f"no optimal-action oracle for env {env_name!r}; games with one: {', '.join(with_one)}")
    return build(**env_config)
