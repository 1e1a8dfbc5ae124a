"""A control of the convention posterior on the bandit: a lookup of the new partner's arm per context, no Bayes.

The posterior weighs the new partner's moves against the training partners' conventions.
This control reads the same moves and nothing of the training partners: in each situation
(the game's convention key, `envs.convention_keys`, of the ego's own observation of the step;
in a simultaneous-move game both seats act on it) where the partner has been seen to move, it
plays the partner's most played move there (lowest on ties): in the bandit only matching
pulls pay, so that is the best response to a partner that always pulls it. Elsewhere it plays
the trained ego's task module alone (its logits, no head: its estimate of the marginal),
frozen as trained. It uses the partner's actions and the situation keys; not the partner's
observation, not the training partners, not the returns.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from rllib_conv.envs.convention_keys import KeyFn
from rllib_conv.partners.base import Partner


class ContextLookup:
    """Counts of the new partner's moves per situation key, read from the ego's side (`envs.seen_moves`)."""

    def __init__(self, key: KeyFn) -> None:
        self.key = key
        self.counts: dict[int, Counter[int]] = {}  # situation key -> how often the partner played each move there

    def observe(self, ego_observations: np.ndarray, ego_moves: np.ndarray, partner_moves: np.ndarray) -> None:
        """Add the partner's moves, each keyed by the ego's observation of the step (`SeenMoves.take`); the ego's moves are not needed."""
        for observation, move in zip(ego_observations, partner_moves):
            self.counts.setdefault(self.key(observation), Counter())[int(move)] += 1

    def seen(self, observation: np.ndarray) -> int | None:
        """The partner's most played move in `observation`'s situation (lowest on ties), or None if it has not moved there."""
        counts = self.counts.get(self.key(np.asarray(observation)))
        return None if counts is None else max(sorted(counts), key=counts.__getitem__)  # the first of the most played

    def player(self, name: str, fallback: Partner) -> "LookupPlayer":
        """The ego playing the lookup as it stands, `fallback` (the trained task module) in unseen situations."""
        return LookupPlayer(name, self, fallback)


class LookupPlayer(Partner):
    """Plays `lookup`'s move where the partner has been seen (and the move is legal), else `fallback`'s."""

    kind = "context_lookup"

    def __init__(self, name: str, lookup: ContextLookup, fallback: Partner) -> None:
        super().__init__(name)
        self.lookup, self.fallback = lookup, fallback

    def _looked_up(self, observation: np.ndarray, action_mask: np.ndarray) -> int | None:
        action = self.lookup.seen(observation)
        return action if action is not None and action_mask[action] else None

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        action = self._looked_up(observation, action_mask)
        return self.fallback.act(observation, action_mask) if action is None else action

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        out = np.array(self.fallback.action_probs(observations, action_masks), dtype=np.float64)
        for b, (obs, mask) in enumerate(zip(np.asarray(observations), np.asarray(action_masks))):
            action = self._looked_up(obs, mask)
            if action is not None:
                out[b] = np.eye(out.shape[1])[action]
        return out

    def seed(self, seed: int | None) -> None:
        self.fallback.seed(seed)

    def params(self) -> dict[str, Any]:
        return {"fallback": self.fallback.name}
