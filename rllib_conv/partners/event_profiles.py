"""Event profiles of self-play partners, and HSP's greedy choice of a pool's most diverse members.

HSP (Yu et al., ICLR 2023) trains a large pool of biased partners and keeps the ones that behave
most differently, judged by event-based features: how often each game event happens when a
partner plays. Here a partner's profile is the mean count per episode of every event of its
game (`GameRecord.events`; Overcooked's per-player event flags) for the partner's own seat,
beside the counterpart it was trained with, both acting as partners act (sampling); and
`most_diverse` picks members one by one, each time the one whose profile is furthest (L1) from
those already picked (farthest-point selection), starting from the one furthest from all others.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from rllib_conv import envs
from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import episode_stream
from rllib_conv.partners.kinds import partner_from_spec
from rllib_conv.partners.population import PartnerEntry, Population


def profiled_events(population: Population) -> tuple[str, ...]:
    """The events `population`'s partners are profiled by: its game's; ValueError when it names none."""
    events = envs.game(population.env).events
    if not events:
        raise ValueError(f"population {population.name!r}: game {population.env!r} has no events to profile partners by")
    return events


def event_profile(population: Population, entry: PartnerEntry, episodes: int, seed: int = 0) -> dict[str, float]:
    """`entry` in its seat beside its counterpart: per episode, the team's score and each event of the game (its seat's).

    ValueError when the game names no events or the entry has no counterpart.
    """
    events = profiled_events(population)
    if entry.counterpart is None:
        raise ValueError(f"population {population.name!r}: partner {entry.name!r} has no counterpart to play with")
    env = envs.make_scored(population.env, **population.env_config)
    seat = population.partner_agents[0]
    other = population.ego_agent(env.possible_agents)
    players: dict[str, Partner] = {seat: entry.build(), other: partner_from_spec(entry.counterpart)}
    counts: Counter[str] = Counter()
    stream = episode_stream(env, players, seed, on_infos=lambda infos: counts.update(infos[seat]["events"]))
    score = sum(next(stream)[0] for _ in range(episodes))
    return {"score": score / episodes, **{event: counts[event] / episodes for event in events}}


def most_diverse(profiles: np.ndarray, keep: int) -> list[int]:
    """Indices of `keep` rows of `profiles` [members, features], by farthest-point selection in L1 (see the module
    docstring); ties go to the earlier row. ValueError unless 1 <= keep <= members."""
    profiles = np.asarray(profiles, dtype=float)
    if not 1 <= keep <= len(profiles):
        raise ValueError(f"keep must be between 1 and the {len(profiles)} members, got {keep}")
    distances = np.abs(profiles[:, None, :] - profiles[None, :, :]).sum(-1)
    chosen = [int(np.argmax(distances.sum(1)))]
    nearest = distances[chosen[0]].copy()  # each member's distance to the nearest chosen one
    while len(chosen) < keep:
        nearest[chosen] = -1.0
        chosen.append(int(np.argmax(nearest)))
        nearest = np.minimum(nearest, distances[chosen[-1]])
    return chosen
