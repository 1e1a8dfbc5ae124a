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

import numpy as np

from rllib_conv.adaptation.plan_player import MoveOrFallback
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


class LookupPlayer(MoveOrFallback):
    """Plays `lookup`'s move where the partner has been seen (and the move is legal), else `fallback`'s."""

    kind = "context_lookup"

    def __init__(self, name: str, lookup: ContextLookup, fallback: Partner) -> None:
        super().__init__(name, fallback)
        self.lookup = lookup

    def move(self, observation: np.ndarray) -> int | None:
        return self.lookup.seen(observation)
