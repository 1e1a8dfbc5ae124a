"""The bandit's oracle: the arms with the highest prize in the observed context (exact), and its states.

The bandit's states can be listed (one per context), so the marginals compare a task module
with the oracle on every one of them rather than on sampled play (`GameRecord.states`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.bandit.env import CollaborativeBanditEnv
from rllib_conv.envs.game import OracleFn


def bandit_states(env_config: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Every bandit state (one-hot contexts) with all-legal masks."""
    env = CollaborativeBanditEnv(**env_config)
    return np.eye(env.num_contexts, dtype=np.float32), np.ones((env.num_contexts, env.num_arms), dtype=np.int8)


def bandit_oracle(**env_config: Any) -> OracleFn:
    """Exact oracle of the bandit: the highest-prize arms of the one-hot context."""
    env = CollaborativeBanditEnv(**env_config)
    optimal = (env.prizes == env.prizes.max(axis=1, keepdims=True)).astype(np.float32)
    return lambda obs: np.asarray(obs, dtype=np.float32) @ optimal
