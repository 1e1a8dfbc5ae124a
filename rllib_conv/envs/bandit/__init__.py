"""The collaborative contextual bandit: its env (`env.py`), oracle, convention key and record.

The env's names are handed on here, so `rllib_conv.envs.bandit` is the game as importers know it.
"""

from rllib_conv.envs.bandit.env import (
    PAPER_ARMS,
    PAPER_CONTEXTS,
    TASKS,
    CollaborativeBanditEnv,
    good_arms,
    oracle_marginals,
    paper_prizes,
    user_study_prizes,
)

__all__ = [
    "PAPER_ARMS",
    "PAPER_CONTEXTS",
    "TASKS",
    "CollaborativeBanditEnv",
    "good_arms",
    "oracle_marginals",
    "paper_prizes",
    "user_study_prizes",
]
