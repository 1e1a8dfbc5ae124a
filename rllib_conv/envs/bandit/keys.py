"""The bandit's convention key: each context is its own coordination problem.

The context is both seats' one-hot observation, so the ego answers a seen context with
the convention it follows (`envs.convention_keys`).
"""

from __future__ import annotations

import numpy as np


def bandit_context(observation: np.ndarray) -> int:
    """The bandit's context: the index of its one-hot observation."""
    return int(np.asarray(observation).argmax())
