"""Best responses: games whose ego can plan against a model of its partner.

A game registers `factory(env_config, ego_agent) -> BestResponse | None` when the ego's
best response to a given partner policy can be computed exactly (a small game whose rules
are at hand). A `BestResponse` lists every observation the partner can act on
(`situations`) and, given the partner's action probabilities in each, returns a `Plan`:
the ego's best action per observation. The convention-posterior adapter plans against
its posterior prediction of the new partner's moves (`training.convention_posterior`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np


class Plan(Protocol):
    """The ego's moves against one partner model."""

    def act(self, observation: np.ndarray) -> int | None:
        """The ego's best action in `observation`, or None where the plan has none."""


class BestResponse(Protocol):
    """Plans the ego's best response to a partner given its action probabilities in every situation."""

    def situations(self) -> tuple[np.ndarray, np.ndarray]:
        """Every observation [S, d] the partner can act on, with its action mask [S, A]."""

    def plan(self, predict: np.ndarray) -> Plan:
        """The ego's best response to a partner that plays `predict[s]` ([S, A]) in situation s."""


Factory = Callable[[dict[str, Any], str], "BestResponse | None"]
_FACTORIES: dict[str, Factory] = {}


def register_best_response(env_name: str, factory: Factory) -> None:
    """Register `factory(env_config, ego_agent)` for the game `env_name`; it returns None for seats it cannot plan for."""
    _FACTORIES[env_name] = factory


def best_response(env_name: str, env_config: dict[str, Any], ego_agent: str) -> BestResponse | None:
    """The best-response planner of `env_name` for an ego playing `ego_agent`, or None if the game has none."""
    factory = _FACTORIES.get(env_name)
    return factory(env_config, ego_agent) if factory else None
