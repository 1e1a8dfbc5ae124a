"""Learners: PPO with the marginal regulariser and real freezing."""

from rllib_conv.learners.marginal_learner import (
    HEAD_L2_KEY,
    MARGINAL_REG_KEY,
    MarginalPPOLearner,
    head_size,
    marginal_distance,
)

__all__ = ["HEAD_L2_KEY", "MARGINAL_REG_KEY", "MarginalPPOLearner", "head_size", "marginal_distance"]
