"""`EgoSetup`: an experiment resolved against its population (game, seats, training partners, module IDs).

In a game of k seats the population names the k-1 partner seats; every episode seats one
training partner in each (`modules.mapping`), and the modular ego has a head per team of
partners in seat order (`ego@a+b`: P**(k-1) heads for P training partners). Adapting to a new
team fixes it (`team`): every episode seats that team, and the ego has its one head.

With `model.heads: seat` the weights behind the team heads are one head per (partner seat,
partner) instead, P*(k-1) of them (`weight_heads`): a team's logits and values add those of
its seats' heads (`head_members`). The team heads stay what agents map to and what is saved
(each as one plain head holding the sum, `EgoStack.head_state`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rllib_conv import envs, partners
from rllib_conv.common.methods import method
from rllib_conv.modules import AGG_HEAD_ID, ego_id
from rllib_conv.modules.partner_schedule import load_function
from rllib_conv.partners.population import PartnerEntry, Population, team_name, teams_of
from rllib_conv.training.experiment import ExperimentConfig


@dataclass
class EgoSetup:
    """Everything derived from an experiment: resolved config, population, seats, module IDs."""

    exp: ExperimentConfig
    population: Population
    env_config: dict
    ego_agent: str
    partner_agent: str  # the first partner seat (its spaces are every partner seat's)
    train: list[PartnerEntry]
    partner_agents: list[str] = field(default_factory=list)  # every partner seat; empty: `partner_agent` alone
    team: tuple[str, ...] | None = None  # the one team every episode seats (adaptation); None: every team of `train`

    def __post_init__(self) -> None:
        self.partner_agents = list(self.partner_agents) or [self.partner_agent]

    @property
    def teams(self) -> list[tuple[str, ...]]:
        """Every team of training partners, one per partner seat in seat order (one seat: each partner alone); `team` alone if set."""
        if self.team is not None:
            return [self.team]
        return [tuple(e.name for e in team) for team in teams_of(self.train, len(self.partner_agents))]

    @property
    def head_ids(self) -> list[str]:
        """The ego heads being trained (one per training partner, or team of them; one for BaselineAgg)."""
        return [AGG_HEAD_ID] if method(self.exp.method).single_head else [ego_id(team_name(t)) for t in self.teams]

    @property
    def seat_heads(self) -> bool:
        """Whether the team heads are sums of per-(seat, partner) heads (`model.heads: seat`, several partner seats, a head per partner)."""
        return self.exp.model.heads == "seat" and len(self.partner_agents) > 1 and not method(self.exp.method).single_head

    @property
    def weight_heads(self) -> list[str]:
        """The heads that hold weights, in stack order: the team heads, or with `seat_heads` one per (seat, partner) of the teams.

        A seat head is named `ego@<seat>=<partner>` (the name seeds its initial weights).
        """
        if not self.seat_heads:
            return self.head_ids
        return [_seat_head(seat, name) for i, seat in enumerate(self.partner_agents) for name in self._seat_partners(i)]

    @property
    def head_members(self) -> list[list[int]]:
        """Per team head (`head_ids` order), the `weight_heads` whose outputs it adds: itself, or one per partner seat."""
        if not self.seat_heads:
            return [[h] for h in range(len(self.head_ids))]
        index = {mid: i for i, mid in enumerate(self.weight_heads)}
        return [[index[_seat_head(seat, name)] for seat, name in zip(self.partner_agents, team)] for team in self.teams]

    def _seat_partners(self, seat_index: int) -> list[str]:
        """The partners that sit in partner seat `seat_index` in some team, in order of first appearance."""
        return list(dict.fromkeys(team[seat_index] for team in self.teams))

    def head_for(self, partner_name: str | tuple[str, ...]) -> str:
        """The ego head that plays with `partner_name` (a team: one name per partner seat; the shared head for single-network methods)."""
        names = (partner_name,) if isinstance(partner_name, str) else tuple(partner_name)
        return AGG_HEAD_ID if method(self.exp.method).single_head else ego_id(team_name(names))


def _seat_head(seat: str, partner: str) -> str:
    """The name of the seat head for `partner` in partner seat `seat` (`ego@player_1=H1`); it seeds the head's weights."""
    return ego_id(f"{seat}={partner}")


def resolve(exp: ExperimentConfig) -> EgoSetup:
    """Load the population, check it fits the game, and fill in the game's defaults."""
    pop = partners.get(exp.population)
    return setup_for(exp, pop, pop.entries("train"))


def setup_for(exp: ExperimentConfig, pop: Population, train: list[PartnerEntry], team: tuple[str, ...] | None = None) -> EgoSetup:
    """The setup training the ego of `exp` against the partners `train` of `pop` (only their team `team`, one per partner seat, if given)."""
    if exp.env is not None and exp.env != pop.env:
        raise ValueError(f"env {exp.env!r} does not match population {pop.name!r}, which is for {pop.env!r}")
    env_config = {**pop.env_config, **exp.env_config}
    agents = list(envs.make(pop.env, **env_config).possible_agents)
    seats = pop.partner_agents
    if len(agents) == 2 and (len(seats) != 1 or seats[0] not in agents):
        raise ValueError(
            f"population {pop.name!r}: partner_agent {pop.partner_agent!r} must be one of the game's two agents {agents}"
        )
    if len(set(seats)) != len(seats) or not set(seats) <= set(agents) or len(seats) != len(agents) - 1:
        raise ValueError(
            f"population {pop.name!r}: partner_agent {pop.partner_agent!r} must list every seat but the ego's, "
            f"{len(agents) - 1} of the game's {len(agents)} agents {agents}"
        )
    if not train:
        raise ValueError(f"population {pop.name!r} has no partners to train with")
    if len(seats) > 1 and exp.mapping.function is not None:
        raise ValueError(f"mapping.function chooses one partner seat's partner; population {pop.name!r} has {len(seats)}")
    ego_agent = next(a for a in agents if a not in seats)
    _check_mapping(exp, [e.name for e in train])
    if team is not None and (len(team) != len(seats) or not set(team) <= {e.name for e in train}):
        raise ValueError(f"team {list(team)} must name one of the partners {[e.name for e in train]} for each seat of {seats}")
    return EgoSetup(
        exp.resolve(pop.env), pop, env_config, ego_agent, seats[0], train, seats, None if team is None else tuple(team)
    )


def _check_mapping(exp: ExperimentConfig, partners: list[str]) -> None:
    """The mapping's weights name training partners (and weigh one); its function can be imported."""
    mapping = exp.mapping
    if mapping.weights is not None:
        unknown = sorted(set(mapping.weights) - set(partners))
        if unknown:
            raise ValueError(f"mapping.weights: {unknown} are not training partners; they are {partners}")
        if not any(mapping.weights.get(p, 0.0) > 0 for p in partners):
            raise ValueError(f"mapping.weights: no training partner has a positive weight ({mapping.weights})")
    if mapping.function is not None:
        load_function(mapping.function)
