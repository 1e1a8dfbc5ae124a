"""Seat views: another seat's situation as the ego's own observation shows it, by the game's rules.

An adapter that judges a partner's moves against models of known partner types needs the
situation each move was made in. The partner's own observation may hold what the ego never
sees (`GameRecord.partner_sees`); a seat view rebuilds the partner's observation and legal
moves from the ego's own observation and last move instead (what `envs.seen_moves` records),
so the adapter learns only from what the ego's seat observes. A game declares
`factory(env_config, ego_agent, agent) -> SeatView | None` in its record
(`GameRecord.seat_view`; Level-Based Foraging's is `envs/lbf/seat_view.py`), None where the
ego's observation does not show that seat's situation (LBF with partial sight).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from rllib_conv.envs.registry import game


class SeatView(Protocol):
    """Rebuilds one seat's observation and action mask from the ego's."""

    def __call__(self, observation: np.ndarray, ego_move: int) -> tuple[np.ndarray, np.ndarray]:
        """(observation [d], 0/1 mask [A]) of the seat, from the ego's `observation` and the ego's `ego_move` before its
        move (-1: none yet); in a simultaneous-move game the ego's observation is the step's and its move is not needed."""


def seat_view(env_name: str, env_config: dict[str, Any], ego_agent: str, agent: str) -> SeatView | None:
    """Seat `agent`'s view as the ego in `ego_agent` sees it in `env_name`, or None where the game cannot rebuild it."""
    factory = game(env_name).seat_view
    return factory(env_config, ego_agent, agent) if factory else None
