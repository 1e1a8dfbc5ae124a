"""Best responses: games whose ego can plan against a model of its partner.

A game declares `factory(env_config, ego_agent) -> BestResponse | None` in its record
(`GameRecord.best_response`; blocks' is `envs/blocks/best_response.py`) when the ego's
best response to a given partner policy can be computed exactly (a small game whose rules
are at hand). A `BestResponse` lists every observation the partner can act on
(`situations`) and, given the partner's action probabilities in each, returns a `Plan`:
the ego's best action per observation. The convention-posterior adapter plans against
its posterior prediction of the new partner's moves (`adaptation.convention_posterior`).

A game whose best response to a fixed partner has a known expected score declares it too
(`GameRecord.best_response_return`: the bandit's `envs/bandit/best_response.py`, blocks'
beside its planner); `best_response_return` asks for it, and `rllib-conv evaluate`
normalises returns by it.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from rllib_conv.envs.registry import game


class Plan(Protocol):
    """The ego's moves against one partner model: a legal move at every move of the planning seat.

    Players that play a plan (the convention posterior's, its controls') rely on it: their
    moves are then fixed before an episode, so a game's exact return scores them.
    """

    def act(self, observation: np.ndarray) -> int | None:
        """The ego's best action in `observation`; None only where it is not the planning seat's move."""


class BestResponse(Protocol):
    """Plans the ego's best response to a partner given its action probabilities in every situation."""

    def situations(self) -> tuple[np.ndarray, np.ndarray]:
        """Every observation [S, d] the partner can act on, with its action mask [S, A]."""

    def plan(self, predict: np.ndarray) -> Plan:
        """The ego's best response to a partner that plays `predict[s]` ([S, A]) in situation s."""

    def follows(self, observation: np.ndarray, action: int) -> int | None:
        """The partner's situation (an index into `situations`) that the ego's `action` in its own `observation` leads to,
        by the game's rules; None where the partner does not move next. An adapter that learns a partner model from the
        partner's moves keys them by it, from the ego's side alone (`envs.seen_moves`)."""


def best_response(env_name: str, env_config: dict[str, Any], ego_agent: str) -> BestResponse | None:
    """The best-response planner of `env_name` for an ego playing `ego_agent`, or None if the game has none."""
    factory = game(env_name).best_response
    return factory(env_config, ego_agent) if factory else None


def best_response_return(env_name: str, env_config: dict[str, Any], ego_agent: str, partner: Any) -> float | None:
    """The expected score of the best ego in seat `ego_agent` against the fixed `partner`, exact; None where unknown."""
    bound = game(env_name).best_response_return
    return bound(partner, env_config, ego_agent) if bound else None
