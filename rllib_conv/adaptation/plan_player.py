"""The ego playing a best-response plan (`envs.best_response.Plan`), with another player where the plan has no move.

The planner controls of the convention posterior (`counts_planner`, `prior_planner`) play
the plan of the game's exact planner against their own partner model, as the posterior
plays its plan against its prediction; where the plan has no move (not the planning seat's
turn), or its move is not legal, `fallback` plays.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.best_response import Plan
from rllib_conv.partners.base import Partner


class MoveOrFallback(Partner):
    """Plays its own `move` wherever that is a legal move, else `fallback`'s (the controls' players: a plan, a lookup)."""

    def __init__(self, name: str, fallback: Partner) -> None:
        super().__init__(name)
        self.fallback = fallback

    def move(self, observation: np.ndarray) -> int | None:
        """This player's own move in `observation`, or None where it has none."""
        raise NotImplementedError

    def chosen(self, observation: np.ndarray, action_mask: np.ndarray) -> int | None:
        """`move` in `observation` if it is legal, else None."""
        action = self.move(np.asarray(observation))
        return action if action is not None and action_mask[action] else None

    @property
    def batchable(self) -> bool:  # type: ignore[override]
        """Its own moves are a function of the observation (fixed while it plays): batchable where its fallback is."""
        return self.fallback.batchable

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        action = self.chosen(observation, action_mask)
        return self.fallback.act(observation, action_mask) if action is None else action

    def act_batch(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        observations, action_masks = np.asarray(observations), np.asarray(action_masks)
        chosen = [self.chosen(obs, mask) for obs, mask in zip(observations, action_masks)]
        out = np.array([-1 if a is None else a for a in chosen], dtype=np.int64)
        rest = [b for b, a in enumerate(chosen) if a is None]
        if rest:  # the fallback chooses for all its rows at once
            out[rest] = self.fallback.act_batch(observations[rest], action_masks[rest])
        return out

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        out = np.array(self.fallback.action_probs(observations, action_masks), dtype=np.float64)
        for b, (obs, mask) in enumerate(zip(np.asarray(observations), np.asarray(action_masks))):
            action = self.chosen(obs, mask)
            if action is not None:
                out[b] = np.eye(out.shape[1])[action]
        return out

    def seed(self, seed: int | None) -> None:
        self.fallback.seed(seed)

    def params(self) -> dict[str, Any]:
        return {"fallback": self.fallback.name}


class PlanPlayer(MoveOrFallback):
    """Plays `plan`'s move wherever it has a legal one, else `fallback`'s; the plan never changes while it plays."""

    kind = "plan"

    def __init__(self, name: str, plan: Plan, fallback: Partner) -> None:
        super().__init__(name, fallback)
        self.plan = plan

    def move(self, observation: np.ndarray) -> int | None:
        return self.plan.act(observation)
