"""Scripted Hanabi partners: uniform random legal play and a simple hint/play convention.

Both act from `(observation vector, action mask)` alone, like any other
`Partner`; the rule partner reads the observation back through
`rllib_conv.envs.hanabi.decode_card_knowledge`, so it needs to know the game
config the vector was encoded with (the paper's small Hanabi by default). The built-in
population `hanabi-scripted` is declared here.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.hanabi import (
    HanabiConfig,
    HanabiMoveIds,
    card_count,
    decode_card_knowledge,
)
from rllib_conv.partners.base import Partner
from rllib_conv.partners.kinds import register_kind
from rllib_conv.partners.population import Population, from_partners, register_builtin


def _legal_ids(action_mask: np.ndarray, who: str) -> np.ndarray:
    """Return the legal action ids of `action_mask`, raising ValueError if there are none."""
    legal = np.flatnonzero(np.asarray(action_mask))
    if len(legal) == 0:
        raise ValueError(f"{who}: the action mask has no legal action; is it this player's turn?")
    return legal


@register_kind
class RandomLegalPartner(Partner):
    """Uniformly random over the legal actions of any masked game (it never looks at the observation)."""

    kind = "random_legal"
    batchable = True  # a function of each observation (and its own RNG): it may choose for many games at once

    def __init__(self, name: str = "random_legal", seed: int = 0) -> None:
        """Create the partner with its own RNG seeded by `seed`."""
        super().__init__(name)
        self._seed = int(seed)
        self._rng = np.random.default_rng(self._seed)

    def seed(self, seed: int | None) -> None:
        """Re-create the partner's RNG from `seed` (None: fresh entropy)."""
        self._rng = np.random.default_rng(seed)

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """Uniform over each row's legal actions."""
        legal = np.asarray(action_masks, dtype=np.float64)
        return legal / legal.sum(axis=1, keepdims=True)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        """Return a legal action drawn uniformly; ValueError if none is legal."""
        legal = _legal_ids(action_mask, self.name)
        return int(legal[self._rng.integers(len(legal))])

    def params(self) -> dict[str, Any]:
        """Return the constructor arguments (the constructor seed, not later `seed()` calls)."""
        return {"seed": self._seed}


@register_kind
class HanabiRulePartner(Partner):
    """A deterministic "hint what is playable, play what is known playable" Hanabi player.

    Each turn, from its own observation only:

    1. play a card that is known to be playable (every (colour, rank) still
       possible for it, after ruling out copies it can see, is playable);
    2. else, if an information token is left and another player holds a
       playable card it does not know is playable, hint that card's rank (or
       its colour if the rank is already known);
    3. else discard the card whose possible identities are least likely to be
       useful (already played or dead cards first, last copies last; ties go
       to the oldest card), if discarding is legal;
    4. else give a legal hint, preferring one that tells something new about
       the lowest-ranked card; failing all that, the lowest legal move id.
    """

    kind = "hanabi_rule"
    batchable = True  # a function of each observation (and its own RNG): it may choose for many games at once
    deterministic = True

    def __init__(self, name: str = "hanabi_rule", **game: int) -> None:
        """Create the partner for observations of the game `game` (`HanabiConfig` keywords, validated like the env's)."""
        super().__init__(name)
        self._cfg = HanabiConfig(**game).game_keys()
        self._ids = HanabiMoveIds(self._cfg["colors"], self._cfg["ranks"], self._cfg["players"], self._cfg["hand_size"])

    def params(self) -> dict[str, Any]:
        """Return the game config this partner decodes observations with."""
        return dict(self._cfg)

    # ------------------------------------------------------------------ policy
    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        """Return the rule's move id for one card-knowledge observation; ValueError if nothing is legal."""
        mask = np.asarray(action_mask)
        if len(mask) != self._ids.num_moves:
            raise ValueError(f"{self.name}: action mask has {len(mask)} entries, expected {self._ids.num_moves} for {self._cfg}")
        legal = _legal_ids(mask, self.name)
        view = decode_card_knowledge(observation, **self._cfg)
        if view["knowledge"] is None:
            raise ValueError(f"{self.name} needs card-knowledge observations (observation_type 1 or 2), got minimal")
        fireworks = view["fireworks"]
        unseen = self._unseen_counts(view)

        def playable(card: tuple[int, int]) -> bool:
            return card[1] == fireworks[card[0]]

        # 1. Play a card known to be playable.
        for i, possible in enumerate(view["own_possible"]):
            candidates = [c for c in possible if unseen[c[0]][c[1]] > 0] or list(possible)
            if all(playable(c) for c in candidates) and mask[self._ids.play(i)]:
                return self._ids.play(i)

        # 2. Tell another player about a playable card it does not know is playable.
        if view["information_tokens"] > 0:
            for offset in range(1, self._cfg["players"]):
                for j, card in enumerate(view["hands"][offset]):
                    if not playable(card):
                        continue
                    known = view["knowledge"][offset][j]
                    if all(playable(c) for c in known["possible"]):
                        continue
                    if known["rank"] is None:
                        move = self._ids.reveal_rank(offset, card[1])
                    elif known["color"] is None:
                        move = self._ids.reveal_color(offset, card[0])
                    else:
                        continue
                    if mask[move]:
                        return move

        # 3. Discard the least useful card.
        discardable = [i for i in range(len(view["own_possible"])) if mask[self._ids.discard(i)]]
        if discardable:
            return self._ids.discard(min(discardable, key=lambda i: (self._usefulness(view["own_possible"][i], view, unseen), i)))

        # 4. Any hint, preferably an informative one about a low card.
        hint = self._informative_hint(view, mask)
        if hint is not None:
            return hint
        hints = [a for a in legal if a >= self._ids.play(self._cfg["hand_size"])]
        return int(hints[0] if hints else legal[0])

    # ----------------------------------------------------------------- helpers
    def _unseen_counts(self, view: dict[str, Any]) -> list[list[int]]:
        """Return [colour][rank] copies not visible to the observer (in the deck or its own hand)."""
        colors, ranks = self._cfg["colors"], self._cfg["ranks"]
        counts = [
            [card_count(r, ranks) - view["discard_counts"][c][r] - (1 if r < view["fireworks"][c] else 0) for r in range(ranks)]
            for c in range(colors)
        ]
        for hand in view["hands"][1:]:
            for c, r in hand:
                counts[c][r] -= 1
        return counts

    def _usefulness(self, possible: set[tuple[int, int]], view: dict[str, Any], unseen: list[list[int]]) -> float:
        """Return the expected value of keeping a card: 0 useless, 1 useful, 2 last copy (+0.5 if playable)."""
        ranks = self._cfg["ranks"]
        total = weight = 0.0
        for c, r in possible:
            w = max(unseen[c][r], 0)
            if w == 0:
                continue
            fw = view["fireworks"][c]
            dead = r < fw or any(view["discard_counts"][c][rr] == card_count(rr, ranks) for rr in range(fw, r))
            if dead:
                value = 0.0
            else:
                value = 1.0 + (1.0 if card_count(r, ranks) - view["discard_counts"][c][r] == 1 else 0.0)
                value += 0.5 if r == fw else 0.0
            total += w * value
            weight += w
        return total / weight if weight else 0.0

    def _informative_hint(self, view: dict[str, Any], mask: np.ndarray) -> int | None:
        """Return a legal hint that reveals something new, aimed at the lowest-ranked card, or None."""
        best: tuple[int, int, int] | None = None
        for offset in range(1, self._cfg["players"]):
            for j, (c, r) in enumerate(view["hands"][offset]):
                known = view["knowledge"][offset][j]
                for move, new in (
                    (self._ids.reveal_rank(offset, r), known["rank"] is None),
                    (self._ids.reveal_color(offset, c), known["color"] is None),
                ):
                    if new and mask[move] and (best is None or (r, offset) < best[:2]):
                        best = (r, offset, move)
        return None if best is None else best[2]


def hanabi_scripted() -> Population:
    """A rule-following Hanabi partner (train) and a uniformly random legal one (test)."""
    return from_partners(
        "hanabi-scripted",
        "hanabi",
        {},
        [HanabiRulePartner("rule")],
        [RandomLegalPartner("random")],
        description="scripted Hanabi players (self-play partners come from `rllib-conv partners train`)",
    )


register_builtin("hanabi-scripted", hanabi_scripted)
