"""PLASTIC (Barrett & Stone 2015; not in the paper): a belief over known partner types, playing the best-matching type's policy.

The field's ad hoc teamwork reference. The ego has met some partner types in training (the
training partners) and holds a policy for each: the trained modular ego's head for that
partner, or, in a game of more than two seats, for that team of partners (`ego@a+b`). Meeting
a new team, PLASTIC keeps a belief over which known type sits in each partner seat, updates it
by Bayes' rule from each seat's observed actions, and plays the policy of the most probable
team. Here:

- **the types** are the trained ego's training partners, whose action probabilities are the
  likelihoods (smoothed with `epsilon` of uniform legal play: a model is never certain);
- **the evidence** is each partner seat's actions as the ego's seat observes them
  (`envs.seen_moves`), each judged in that seat's situation as rebuilt from the ego's own
  observation by the game's rules (`envs.seat_views`), never from the partner's own
  observation: equal information with the other adapters;
- **the belief** is, per seat, the convention posterior's belief over whole known conventions
  (`ConventionPosterior.whole`: the same Bayes update, an even prior); the seats are
  independent a priori, so the team posterior is the product over seats and its most probable
  team is each seat's most probable type (the first in training order on a tie);
- **the policy** is the trained ego (task module and heads, as trained) with the head for the
  most probable team, chosen again after every partner move (`PlasticPlayer`). Before any
  evidence it plays the first team's head.

Barrett & Stone update with a bounded loss (polynomial weights) to survive types that fit no
known one; the smoothing plays that part here. In `rllib-conv adapt` the belief learns from
the env steps of the adaptation's rollouts (PPO trains a fresh head on them beside it, so every
curve spends the same env steps, but PLASTIC never plays that head); each evaluation episode
starts from that belief and updates a copy of it move by move, as PLASTIC does online.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from rllib_conv.adaptation.convention_posterior import ConventionPosterior
from rllib_conv.common.seeds import member_seed
from rllib_conv.envs.seat_views import SeatView
from rllib_conv.modules import ego_id
from rllib_conv.partners.base import Partner
from rllib_conv.partners.population import team_name
from rllib_conv.training.evaluate import ego_head_partner


class Plastic:
    """PLASTIC's belief over which of the known `types` sits in each partner seat (`views`: seat -> its `SeatView`)."""

    def __init__(self, types: Sequence[Partner], views: Mapping[str, SeatView], epsilon: float = 0.05) -> None:
        if not types or not views:
            raise ValueError("PLASTIC needs at least one known partner type and one partner seat")
        self.types = [t.name for t in types]
        self.views = dict(views)
        self.beliefs = {seat: ConventionPosterior(types, None, epsilon=epsilon) for seat in self.views}

    @property
    def seats(self) -> list[str]:
        """The partner seats, in order."""
        return list(self.views)

    def observe(self, ego_observations: np.ndarray, ego_moves: np.ndarray, moves: np.ndarray, seats: np.ndarray) -> None:
        """Add the partner seats' moves as the ego's seat recorded them (`SeenMoves.take_seated`)."""
        for seat, view in self.views.items():
            rows = np.flatnonzero(np.asarray(seats) == seat)
            if not len(rows):
                continue
            rebuilt = [view(ego_observations[i], int(ego_moves[i])) for i in rows]
            observations = np.stack([o for o, _ in rebuilt])
            masks = np.stack([m for _, m in rebuilt]).astype(np.int8)
            actions = np.asarray(moves)[rows]
            masks[np.arange(len(rows)), actions] = 1  # a move the rebuilt mask missed is still evidence, never impossible
            self.beliefs[seat].observe(observations, masks, actions)

    def seat_belief(self, seat: str) -> np.ndarray:
        """[K]: the probability that each known type (in `types` order) sits in `seat`."""
        return self.beliefs[seat].whole()

    def team_belief(self) -> dict[tuple[str, ...], float]:
        """The probability of every team of known types (one per partner seat, in seat order): the seats' product."""
        per_seat = [self.seat_belief(seat) for seat in self.seats]
        return {
            tuple(self.types[k] for k in ks): float(np.prod([p[k] for p, k in zip(per_seat, ks)]))
            for ks in itertools.product(range(len(self.types)), repeat=len(per_seat))
        }

    def team(self) -> tuple[str, ...]:
        """The most probable team: each seat's most probable type (the first in `types` order on a tie)."""
        return tuple(self.types[int(np.argmax(self.seat_belief(seat)))] for seat in self.seats)

    def head_id(self) -> str:
        """The trained ego's head for the most probable team (`ego@a+b`; `ego@a` with one partner seat)."""
        return ego_id(team_name(self.team()))

    def copy(self) -> "Plastic":
        """An independent copy of the evidence (the types and views are shared)."""
        other = object.__new__(Plastic)
        other.types, other.views = self.types, self.views
        other.beliefs = {seat: belief.copy() for seat, belief in self.beliefs.items()}
        return other

    def head_ids(self) -> list[str]:
        """The heads of every team of known types, in `team_belief` order: the policies PLASTIC may play."""
        return [ego_id(team_name(team)) for team in itertools.product(self.types, repeat=len(self.seats))]

    def player(self, trained: Any) -> "PlasticPlayer":
        """The trained ego (`ConventionMultiRLModule`) playing by PLASTIC from the evidence so far (`PlasticPlayer`)."""
        return PlasticPlayer("plastic", self, trained)


class PlasticPlayer(Partner):
    """The trained ego playing by PLASTIC, as a `Partner` (for `play_episodes`): the head of the most probable team.

    Each episode starts from `plastic` (the evidence so far) and updates a copy after every move
    of a partner seat, as the ego's seat sees it: the ego's own last observation and move (kept
    when it acts), then that seat's action. The partner's own observation, which `observe_other`
    is handed, is never read. `action_probs` is the head chosen before any move of the episode.
    """

    kind = "plastic"
    learns_in_play = True

    def __init__(self, name: str, plastic: Plastic, trained: Any) -> None:
        super().__init__(name)
        missing = sorted(set(plastic.head_ids()) - set(trained.head_ids()))
        if missing:
            raise ValueError(f"PLASTIC plays a head per team of known types, but the trained ego has no {missing}")
        self.plastic = plastic
        self.heads = {mid: ego_head_partner(trained, mid) for mid in plastic.head_ids()}
        self.start_episode()

    def seed(self, seed: int | None) -> None:
        for i, head in enumerate(self.heads.values()):
            head.seed(None if seed is None else member_seed(seed, i))

    def params(self) -> dict[str, Any]:
        return {"types": self.plastic.types, "seats": self.plastic.seats}

    def start_episode(self) -> None:
        self._live = self.plastic.copy()
        self._observation: np.ndarray | None = None
        self._move = -1

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        self._observation = np.array(observation, dtype=np.float32)
        self._move = self.heads[self._live.head_id()].act(observation, action_mask)
        return self._move

    def observe_other(self, observation: np.ndarray, action_mask: np.ndarray, action: int, agent: str | None = None) -> None:
        if agent in self._live.views and self._observation is not None:  # keyed by the ego's view, not `observation`
            self._live.observe(
                self._observation[None], np.array([self._move]), np.array([action]), np.array([agent], dtype=object)
            )

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        return self.heads[self.plastic.head_id()].action_probs(observations, action_masks)
