"""The bandit's best-response bound: what the best ego can expect against a partner whose arm probabilities are known.

Episodes are one step and both seats see the context, so the best response pulls, in each
context, the arm the partner's pulls pay most on: `max_a p(a | c) * prize[c, a]`, averaged
over the uniform contexts. The game is symmetric: the same for either seat.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.bandit.env import CollaborativeBanditEnv
from rllib_conv.envs.bandit.oracle import bandit_states


def bandit_best_response_return(partner: Any, env_config: dict[str, Any], ego_agent: str) -> float | None:
    """The best response's expected return against `partner` (any seat); None if the partner cannot say what it draws from."""
    contexts, masks = bandit_states(env_config)
    try:
        probs = np.asarray(partner.action_probs(contexts, masks), dtype=np.float64)
    except ValueError:  # a partner that does not say what its actions are drawn from
        return None
    return float(np.mean(np.max(probs * CollaborativeBanditEnv(**env_config).prizes, axis=1)))
