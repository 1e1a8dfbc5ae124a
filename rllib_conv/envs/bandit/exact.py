"""The bandit's exact expected return of two fixed policies: contexts uniform, a prize when both pull the same arm."""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.bandit.env import CollaborativeBanditEnv


def bandit_exact_return(policies: dict[str, Any], env_config: dict[str, Any]) -> float | None:
    """sum over contexts and arms of p0 * p1 * prize, averaged over contexts; None if a policy cannot say what it draws from.

    One-step episodes: a player that learns from earlier episodes is scored as it stands.
    """
    env = CollaborativeBanditEnv(**env_config)
    contexts = np.eye(env.num_contexts, dtype=np.float32)
    mask = np.ones((env.num_contexts, env.num_arms), dtype=np.int8)
    try:
        p0, p1 = (policies[a].action_probs(contexts, mask) for a in ("player_0", "player_1"))
    except ValueError:  # a policy that does not say what its actions are drawn from
        return None
    return float(np.mean(np.sum(p0 * p1 * env.prizes, axis=1)))
