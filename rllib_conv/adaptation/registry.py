"""The adapters by name: the vocabulary `rllib-conv adapt` and the study server choose from, bound to their code.

The records themselves (names, what each uses, old spellings, `choose`) are
`rllib_conv.common.adapters`: data without torch or Ray, so that the analysis (which may
import only `rllib_conv.common`), the configs and the server's argument checks read them
without loading a network. This module is the adaptation package's door to them: it binds
each name to the code that runs it (`IMPLEMENTED_BY`) and checks a choice against a trained
ego (`check_trained_ego`) and against what the game lets the ego observe (`check_information`);
the adapt pipeline imports them from here.
"""

from __future__ import annotations

from rllib_conv.adaptation import convention_posterior, fine_tune_guard, head_pick
from rllib_conv.common.adapters import (
    ADAPTERS,
    FRESH,
    GUARD,
    OLD_SPELLINGS,
    PICK,
    POSTERIOR,
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
from rllib_conv.envs.registry import game

__all__ = [
    "ADAPTERS",
    "FRESH",
    "GUARD",
    "IMPLEMENTED_BY",
    "OLD_SPELLINGS",
    "PICK",
    "POSTERIOR",
    "Adapter",
    "StartName",
    "Surface",
    "Uses",
    "adapter",
    "canonical",
    "check_information",
    "check_trained_ego",
    "choose",
    "names",
]

# The code each adapter runs (the fresh head is the pipelines' own PPO adaptation and the server's table agent).
IMPLEMENTED_BY = {
    PICK: head_pick.pick_head,
    POSTERIOR: convention_posterior.ConventionPosterior,
    GUARD: fine_tune_guard.FineTuneGuard,
}


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
