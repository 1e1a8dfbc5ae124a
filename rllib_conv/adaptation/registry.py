"""The adapters by name: the vocabulary `rllib-conv adapt` and the study server choose from, bound to their code.

The records themselves (names, what each uses, old spellings, `choose`) are
`rllib_conv.common.adapters`: data without torch or Ray, so that the analysis (which may
import only `rllib_conv.common`), the configs and the server's argument checks read them
without loading a network. This module is the adaptation package's door to them: it binds
each name to the code that runs it (`IMPLEMENTED_BY`) and checks a choice against a trained
ego (`check_trained_ego`), against what the game lets the ego observe (`check_information`) and
against what the game offers (`check_game`: a convention key, a planner, simultaneous moves);
the adapt pipeline imports them from here.
"""

from __future__ import annotations

from typing import Any

from pettingzoo import ParallelEnv

from rllib_conv.adaptation import (
    context_lookup,
    convention_posterior,
    counts_planner,
    fine_tune_guard,
    head_pick,
    plastic,
    prior_planner,
)
from rllib_conv.common.adapters import (
    ADAPTERS,
    CONTROLS,
    COUNTS_PLANNER,
    FRESH,
    GUARD,
    KNOWN_SEATS,
    LOOKUP,
    OLD_SPELLINGS,
    PICK,
    PLASTIC,
    POSTERIOR,
    PRIOR_PLANNER,
    Adapter,
    StartName,
    Surface,
    Uses,
    adapter,
    canonical,
    choose,
    names,
)
from rllib_conv.common.methods import Method
from rllib_conv.envs.best_response import best_response
from rllib_conv.envs.registry import game, make
from rllib_conv.envs.seat_views import seat_view

__all__ = [
    "ADAPTERS",
    "CONTROLS",
    "COUNTS_PLANNER",
    "FRESH",
    "GUARD",
    "IMPLEMENTED_BY",
    "KNOWN_SEATS",
    "LOOKUP",
    "OLD_SPELLINGS",
    "PICK",
    "PLASTIC",
    "POSTERIOR",
    "PRIOR_PLANNER",
    "Adapter",
    "StartName",
    "Surface",
    "Uses",
    "adapter",
    "canonical",
    "check_game",
    "check_information",
    "check_seats",
    "check_trained_ego",
    "choose",
    "names",
]

# The code each adapter runs (the fresh head is the pipelines' own PPO adaptation and the server's table agent).
IMPLEMENTED_BY = {
    PICK: head_pick.pick_head,
    POSTERIOR: convention_posterior.ConventionPosterior,
    GUARD: fine_tune_guard.FineTuneGuard,
    LOOKUP: context_lookup.ContextLookup,
    COUNTS_PLANNER: counts_planner.CountsPlanner,
    PRIOR_PLANNER: prior_planner.PriorPlanner,
    PLASTIC: plastic.Plastic,
}


def check_game(start: str, game_name: str, env_config: dict[str, Any], ego_agent: str) -> None:
    """ValueError unless the game has what adapter `start` needs of it (`Adapter.needs_game`) for an ego in seat `ego_agent`."""
    record, name = game(game_name), canonical(start)
    for need in adapter(start).needs_game:
        if need == "convention_key" and record.convention_key is None:
            raise ValueError(f"head_init {name!r} looks moves up by situation, but {game_name!r} has no convention key")
        if need == "best_response" and best_response(game_name, env_config, ego_agent) is None:
            raise ValueError(f"head_init {name!r} plans a best response, but {game_name!r} has no planner for seat {ego_agent!r}")
        if need == "seat_view":
            reads = f"head_init {name!r} reads each partner's moves in its situation as the ego's own observation shows it"
            if record.seat_view is None:
                raise ValueError(f"{reads}, and {game_name!r} cannot rebuild a partner's situation from it (no seat view)")
            agents = make(game_name, **env_config).possible_agents
            blind = [a for a in agents if a != ego_agent and seat_view(game_name, env_config, ego_agent, a) is None]
            if blind:
                raise ValueError(
                    f"{reads}, but in {game_name!r} with these settings it does not show the situation of {blind[0]!r}"
                    + (f" (a partner sees {record.partner_sees})" if record.partner_sees else "")
                )
        if need == "simultaneous" and not isinstance(make(game_name, **env_config), ParallelEnv):
            raise ValueError(
                f"head_init {name!r} keys the partner's moves by the ego's observation of the same step, but in {game_name!r} "
                "the seats take turns"
            )


def check_seats(start: str, game_name: str, seats: int) -> None:
    """ValueError unless adapter `start` runs in a game of `seats` seats (more than two: `Adapter.many_seats`)."""
    record = adapter(start)
    if seats > 2 and not record.many_seats:
        able = [a.name for a in ADAPTERS.values() if a.role == "start" and a.many_seats and "adapt" in a.uses]
        what = "guard: true" if record.role == "guard" else f"head_init {record.name!r}"
        raise ValueError(
            f"{what} adapts to one partner in a game of two seats; {game_name!r} has {seats} "
            f"(a new partner is a team there): "
            + ("leave it out" if record.role == "guard" else f"use head_init {' or '.join(able)}")
        )


def check_information(start: str, game_name: str, surface: Surface = "adapt") -> None:
    """ValueError unless adapter `start` uses only what the ego observes in `game_name`.

    An adapter that reads the partner's moves in the partner's own situation (`Uses.partner_situation`) would
    see what the game hides from the ego where the partner's observation shows more (`GameRecord.partner_sees`).
    """
    hidden = game(game_name).partner_sees
    if hidden is not None and adapter(start).uses[surface].partner_situation:
        raise ValueError(
            f"head_init {canonical(start)!r} reads the partner's moves in the situation the partner saw, which in "
            f"{game_name!r} shows {hidden}: it would adapt on information the ego does not have; use fresh or pick"
        )


def check_trained_ego(start: str, trained: Method, what: str) -> None:
    """ValueError unless the ego trained by method `trained` can adapt by `start` (one head per training partner where needed).

    `what` names the ego in the message (its folder, or the argument that gave it).
    """
    if adapter(start).needs_partner_heads and trained.single_head:
        raise ValueError(
            f"head_init {canonical(start)!r} needs one head per training partner, but the ego in {what} was trained with "
            f"method {trained.name!r} (one shared head)"
        )
