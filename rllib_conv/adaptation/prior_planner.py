"""A control of the convention posterior on blocks: its planner against its prior, never updated.

The posterior starts from a prior over the training partners' conventions (whole, or
recombined situation by situation) and updates it with the new partner's moves. This control
plans the same exact best response (`envs.best_response`) to the posterior's prediction
before any evidence, once, and plays that plan throughout: what the training partners' policies
and the planner give without a single move of the new partner. It uses the training
partners' policies and a model of the game; where the plan has no move, the trained ego's
task module plays.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rllib_conv.adaptation.convention_posterior import ConventionPosterior
from rllib_conv.adaptation.plan_player import PlanPlayer
from rllib_conv.envs.best_response import BestResponse
from rllib_conv.partners.base import Partner


class PriorPlanner:
    """The best response to the posterior's prior prediction over `models` (the training partners), planned once."""

    def __init__(
        self, planner: BestResponse, models: Sequence[Partner], recombined: float = 0.5, novel: float = 0.1, epsilon: float = 0.05
    ) -> None:
        # No situation key: with no evidence the posterior's prediction is its prior in every situation.
        self.prior = ConventionPosterior(models, None, recombined, novel, epsilon).predictive(*planner.situations())
        self.plan = planner.plan(self.prior)

    def observe(self, ego_observations: np.ndarray, ego_moves: np.ndarray, partner_moves: np.ndarray) -> None:
        """The new partner's moves change nothing: the prior is frozen."""

    def player(self, name: str, fallback: Partner) -> PlanPlayer:
        """The ego playing the one plan, `fallback` where the plan has no move."""
        return PlanPlayer(name, self.plan, fallback)
