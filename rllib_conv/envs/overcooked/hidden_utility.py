"""Hidden utilities: a seat rewarded by a weighted count of its own kitchen events (HSP's biased partners).

Hidden-utility self-play (HSP; Yu et al., ICLR 2023) models a human partner as optimising a
reward of its own: a weighted sum of events (onions picked up, dishes dropped, soups
delivered, ...), the weights unknown to the ego. A self-play pair in which one seat is
rewarded by `w . events(seat)` and the other by the game's reward yields a "biased" partner.
The events are those `overcooked==0.2.1`'s MDP counts per player in `get_state_transition`
(`event_infos`); a seat's hidden reward counts only the events that seat caused.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from overcooked.mdp.overcooked_mdp import EVENT_TYPES

EVENTS: tuple[str, ...] = tuple(EVENT_TYPES)

HiddenUtility = dict[str, dict[str, float]]  # seat -> {event: weight}


def check_hidden_utility(value: Any, agents: Sequence[str]) -> HiddenUtility:
    """`value` ({seat: {event: weight}}) checked and copied; ValueError naming the bad seat, event or weight."""
    if not isinstance(value, Mapping):
        raise ValueError(f"hidden_utility must map seats to {{event: weight}}, got {value!r}")
    out: HiddenUtility = {}
    for seat, weights in value.items():
        if seat not in agents:
            raise ValueError(f"hidden_utility: unknown seat {seat!r}; seats: {list(agents)}")
        if not isinstance(weights, Mapping) or not weights:
            raise ValueError(f"hidden_utility[{seat!r}] must be a non-empty {{event: weight}} mapping, got {weights!r}")
        for event, weight in weights.items():
            if event not in EVENTS:
                raise ValueError(f"hidden_utility[{seat!r}]: unknown event {event!r}; events: {', '.join(EVENTS)}")
            if isinstance(weight, bool) or not isinstance(weight, int | float) or not math.isfinite(weight):
                raise ValueError(f"hidden_utility[{seat!r}][{event!r}] must be a finite number, got {weight!r}")
        out[seat] = {event: float(weight) for event, weight in weights.items()}
    return out


def events_of(event_infos: Mapping[str, Sequence[bool]], player: int) -> tuple[str, ...]:
    """The events player index `player` caused in one step, in `EVENTS` order."""
    return tuple(event for event in EVENTS if event_infos[event][player])


def event_reward(event_infos: Mapping[str, Sequence[bool]], weights: Mapping[str, float], player: int) -> float:
    """The hidden reward of player index `player` for one step: the weights of the events it caused (`event_infos`)."""
    return float(sum(weight for event, weight in weights.items() if event_infos[event][player]))
