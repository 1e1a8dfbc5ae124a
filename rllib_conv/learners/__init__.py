"""Learners: PPO with the marginal regulariser and real freezing."""

from rllib_conv.learners.marginal_learner import (
    MARGINAL_REG_KEY,
    MarginalPPOLearner,
    marginal_distance,
)

__all__ = ["MARGINAL_REG_KEY", "MarginalPPOLearner", "marginal_distance"]
