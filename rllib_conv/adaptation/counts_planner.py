"""A control of the convention posterior on blocks: its planner against a partner model learned only from the new partner.

The posterior plans the exact best response (`envs.best_response`) to its prediction of the
new partner's moves, a prediction built on the training partners' policies. This control
plans with the same planner against a model that knows nothing but the new partner's own
moves: per partner situation, the counts of its moves plus `prior` (Laplace's rule: one
imagined move of each legal kind), uniform where nothing has been seen. Each move is keyed by
the situation the ego's own last observation and move lead to, by the game's rules
(`BestResponse.follows`, from `envs.seen_moves`): the partner's observation is never read.
It uses the partner's actions and a model of the game, and neither the training partners
nor the returns; where the plan has no move, the trained ego's task module plays.
"""

from __future__ import annotations

import numpy as np

from rllib_conv.adaptation.plan_player import PlanPlayer
from rllib_conv.envs.best_response import BestResponse
from rllib_conv.partners.base import Partner


class CountsPlanner:
    """Counts of the new partner's moves per planner situation, and the best response to the model they give."""

    def __init__(self, planner: BestResponse, prior: float = 1.0) -> None:
        if prior <= 0:
            raise ValueError(f"prior must be > 0 (a model is never certain of an unseen move), got {prior}")
        self.planner, self.prior = planner, prior
        _, masks = planner.situations()
        self.legal = np.asarray(masks, dtype=np.float64)
        self.counts = np.zeros_like(self.legal)

    def observe(self, ego_observations: np.ndarray, ego_moves: np.ndarray, partner_moves: np.ndarray) -> None:
        """Add the partner's moves, each beside the ego's observation and move before it (`SeenMoves.take`)."""
        for observation, ego_move, move in zip(ego_observations, ego_moves, partner_moves):
            situation = self.planner.follows(observation, int(ego_move)) if ego_move >= 0 else None
            if situation is not None:
                self.counts[situation, int(move)] += 1

    def predictive(self) -> np.ndarray:
        """[S, A]: the model's probability of each partner move per situation (counts plus the prior, over legal moves)."""
        weights = (self.counts + self.prior) * self.legal
        return weights / weights.sum(axis=1, keepdims=True)

    def player(self, name: str, fallback: Partner) -> PlanPlayer:
        """The ego playing the best response to the model as it stands (planned now), `fallback` where the plan has no move."""
        return PlanPlayer(name, self.planner.plan(self.predictive()), fallback)
