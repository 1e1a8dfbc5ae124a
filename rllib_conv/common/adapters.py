"""The adapters' vocabulary: every way a trained ego adapts to a new partner, by one name, with what it uses.

One record per adapter. `rllib-conv adapt` chooses one to start from (`head_init`:
`fresh`, `pick`, `posterior`, the posterior's controls or `plastic`) and may add the `guard`; the study server (`rllib-conv
play --adapter`) offers `fresh` and `posterior`; the report names them by the same words.
Each record says, as named fields, what information the adapter uses beyond the trained
ego, on each surface that offers it (`Uses`): the new partner's actions, its returns, the
training partners' policies, the game's situation keys, a model of the game.

The records are data only (no torch, no Ray) so that the analysis, which reads files and
imports only `rllib_conv.common`, can print them; the code each name runs is
`rllib_conv.adaptation` (its `registry` is the door the pipelines and the server use).

Old spellings are accepted where they were shipped, and mapped here only (`OLD_SPELLINGS`):
the server's `--adapter table` is `fresh` (its partner module was a table of logits).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Literal

Surface = Literal["adapt", "play"]
Role = Literal["start", "guard"]

FRESH = "fresh"
PICK = "pick"
POSTERIOR = "posterior"
GUARD = "guard"
# Information-parity controls of the posterior: what it reads, without its Bayes (issue 45).
LOOKUP = "lookup"
COUNTS_PLANNER = "counts-planner"
PRIOR_PLANNER = "prior-planner"
CONTROLS = (LOOKUP, COUNTS_PLANNER, PRIOR_PLANNER)
# The field's ad hoc teamwork reference (Barrett & Stone's PLASTIC): a belief over known partner types.
PLASTIC = "plastic"
# An ego with one head per partner seat and partner (`model.heads: seat`) meeting a team with members it trained with:
# their seat heads kept, a fresh one for each new member.
KNOWN_SEATS = "known-seats"

# What a game must have for an adapter (`Adapter.needs_game`): its record's convention key, a best-response
# planner for the ego's seat, simultaneous moves (a parallel env: each step's situation is one both seats see), or
# a view of every partner seat rebuilt from the ego's own observation (`envs.seat_views`).
GameNeed = Literal["convention_key", "best_response", "simultaneous", "seat_view"]


@dataclass(frozen=True, kw_only=True)
class Uses:
    """What an adapter reads besides the trained ego's weights, on one surface (each field: whether it is read)."""

    # The new partner's own moves, read as evidence (not only through the returns they bring).
    partner_actions: bool = False
    # The situation the new partner saw at each of its moves (its observation): allowed only in games where
    # it holds nothing the ego does not observe (`GameRecord.partner_sees`), so adapters stay on equal information.
    partner_situation: bool = False
    # The returns of episodes played with the new partner (PPO's rollouts, the candidates' scores).
    returns: bool = False
    # The training partners' policies (their action probabilities), as models of known conventions.
    training_policies: bool = False
    # The game's situation keys: which observations carry a convention of their own (`envs.convention_keys`).
    situation_keys: bool = False
    # A model of the game: the best response planned against a partner model (`envs.best_response`),
    # or, in the server, the hindsight targets (which move would have answered the person best).
    game_model: bool = False
    # Which members of a new team are training partners, and in which seats (told, not inferred from their play).
    partner_identities: bool = False

    def names(self) -> list[str]:
        """The names of the fields that are read, in field order (for tables)."""
        return [f.name for f in fields(self) if getattr(self, f.name)]


@dataclass(frozen=True, kw_only=True)
class Adapter:
    """One adapter: its name, whether the paper has it, how it combines, and what it uses where it is offered."""

    name: str
    title: str  # a short description for tables and help texts
    in_paper: bool
    # "start": how the new partner's head starts and is played (`head_init`); "guard": decides
    # whether what fine-tuning learned is used (combines with the starts in `guards`).
    role: Role
    # Needs one trained head per training partner (not a single-network method such as BaselineAgg).
    needs_partner_heads: bool
    # What it uses per surface that offers it; a surface not listed does not offer it.
    uses: dict[Surface, Uses]
    # The module implementing it (for readers of the report).
    module: str
    # For a guard: the starts it may be combined with.
    guards: tuple[str, ...] = ()
    # What the game must have for it (`GameNeed`); a game without is refused before anything runs.
    needs_game: tuple[GameNeed, ...] = ()
    # Runs in games of more than two seats (a new partner there is a team, one per partner seat); False: refused there.
    many_seats: bool = False


ADAPTERS: dict[str, Adapter] = {
    a.name: a
    for a in (
        Adapter(
            name=FRESH,
            title="a fresh partner head on the trained task module (the paper's adapter)",
            in_paper=True,
            role="start",
            needs_partner_heads=False,
            uses={
                "adapt": Uses(returns=True),  # PPO on the rollouts with the new partner
                "play": Uses(partner_actions=True, game_model=True),  # a table of logits stepped towards hindsight targets
            },
            module="rllib_conv/pipelines/adapt.py (adapt), rllib_conv/play/agent.py (play)",
            many_seats=True,
        ),
        Adapter(
            name=PICK,
            title="adapt from the best of the fresh head and the training partners' heads, tried on the new partner",
            in_paper=False,
            role="start",
            needs_partner_heads=True,
            uses={"adapt": Uses(returns=True)},
            module="rllib_conv/adaptation/head_pick.py",
        ),
        Adapter(
            name=POSTERIOR,
            title="play by a posterior over which training partner's convention the new partner follows",
            in_paper=False,
            role="start",
            needs_partner_heads=True,
            uses={
                # The posterior reads the partner's moves against the training partners' models, per situation; where the
                # game has a planner it plays the best response to the prediction; the fresh head beside it adapts by PPO.
                "adapt": Uses(
                    partner_actions=True,
                    partner_situation=True,
                    returns=True,
                    training_policies=True,
                    situation_keys=True,
                    game_model=True,
                ),
                "play": Uses(
                    partner_actions=True, partner_situation=True, training_policies=True, situation_keys=True, game_model=True
                ),
            },
            module="rllib_conv/adaptation/convention_posterior.py",
        ),
        Adapter(
            name=GUARD,
            title="evaluate the ego as it was before any update until fine-tuning is measured better on its own rollouts",
            in_paper=False,
            role="guard",
            needs_partner_heads=False,
            uses={"adapt": Uses(returns=True)},
            module="rllib_conv/adaptation/fine_tune_guard.py",
            guards=(FRESH, POSTERIOR),
            many_seats=True,  # the adapting ego's own returns, whoever its partners
        ),
        Adapter(
            name=LOOKUP,
            title="control: per situation, the partner's most played move once seen there, else the trained task module's "
            "marginal (the posterior's evidence without its Bayes)",
            in_paper=False,
            role="start",
            needs_partner_heads=False,
            # The partner's moves keyed by the ego's own observation of the step (never the partner's); no returns: the
            # trained ego's task logits, frozen, play the unseen situations.
            uses={"adapt": Uses(partner_actions=True, situation_keys=True)},
            module="rllib_conv/adaptation/context_lookup.py",
            needs_game=("convention_key", "simultaneous"),
        ),
        Adapter(
            name=COUNTS_PLANNER,
            title="control: the posterior's planner against a partner model learned only from the new partner's moves "
            "(counts per situation, Laplace prior)",
            in_paper=False,
            role="start",
            needs_partner_heads=False,
            # The partner's situation follows from the ego's own observation and move by the game's rules (the planner's).
            uses={"adapt": Uses(partner_actions=True, game_model=True)},
            module="rllib_conv/adaptation/counts_planner.py",
            needs_game=("best_response",),
        ),
        Adapter(
            name=PRIOR_PLANNER,
            title="control: the posterior's planner against the posterior's prior over the training partners, never updated",
            in_paper=False,
            role="start",
            needs_partner_heads=False,
            uses={"adapt": Uses(training_policies=True, game_model=True)},
            module="rllib_conv/adaptation/prior_planner.py",
            needs_game=("best_response",),
        ),
        Adapter(
            name=PLASTIC,
            title="PLASTIC (Barrett & Stone): a belief over the training partners' types per partner seat, from their moves, "
            "playing the trained ego's head for the most probable team",
            in_paper=False,
            role="start",
            needs_partner_heads=True,
            # Each partner seat's moves, in that seat's situation as rebuilt from the ego's own observation (`seat_view`,
            # a model of the game), judged against the training partners' policies; never a partner's own observation,
            # never the returns (PPO trains the fresh head beside it on the same env steps, but it is never played).
            uses={"adapt": Uses(partner_actions=True, training_policies=True, game_model=True)},
            module="rllib_conv/adaptation/plastic.py",
            needs_game=("seat_view",),
            many_seats=True,
        ),
        Adapter(
            name=KNOWN_SEATS,
            title="a seat-head ego keeps the seat heads of the team's members it trained with (same seat) and adapts them "
            "with a fresh head for each new member",
            in_paper=False,
            role="start",
            needs_partner_heads=True,
            # Told which members are training partners (their names); then PPO on the rollouts, as fresh.
            uses={"adapt": Uses(returns=True, partner_identities=True)},
            module="rllib_conv/pipelines/adapt.py (known_seat_heads)",
            many_seats=True,
        ),
    )
}

# Spellings shipped before the one vocabulary, and the name each means now.
OLD_SPELLINGS: dict[str, str] = {"table": FRESH}


def names(role: Role | None = None, surface: Surface | None = None) -> list[str]:
    """The adapter names in registry order, optionally only those of `role` and those offered on `surface`."""
    return [a.name for a in ADAPTERS.values() if (role is None or a.role == role) and (surface is None or surface in a.uses)]


# The starts `head_init` takes, as a type for configs (pydantic checks a value against them).
StartName = Literal[tuple(names(role="start"))]  # type: ignore[valid-type]


def canonical(name: str) -> str:
    """`name` as the vocabulary spells it now (an old spelling mapped; anything else unchanged)."""
    return OLD_SPELLINGS.get(name, name)


def adapter(name: str) -> Adapter:
    """The record of `name` (old spellings accepted); ValueError naming the adapters if there is none."""
    try:
        return ADAPTERS[canonical(name)]
    except KeyError:
        raise ValueError(f"unknown adapter {name!r}; adapters: {', '.join(ADAPTERS)}") from None


def choose(value: str, surface: Surface, role: Role, what: str) -> str:
    """`value` checked as a `role` adapter offered on `surface`, in today's spelling; ValueError naming `what` otherwise."""
    known = names(role, surface)
    name = canonical(value)
    if name not in known:
        old = [old for old, new in OLD_SPELLINGS.items() if new in known]
        also = f" (or the old spelling {', '.join(map(repr, old))})" if old else ""
        raise ValueError(f"{what} must be one of {known}{also}, got {value!r}")
    return name
