"""`EgoSetup`: an experiment resolved against its population (game, seats, training partners, module IDs)."""

from __future__ import annotations

from dataclasses import dataclass

from rllib_conv import envs, partners
from rllib_conv.common.methods import method
from rllib_conv.modules import AGG_HEAD_ID, ego_id
from rllib_conv.modules.partner_schedule import load_function
from rllib_conv.partners.population import PartnerEntry, Population
from rllib_conv.training.experiment import ExperimentConfig


@dataclass
class EgoSetup:
    """Everything derived from an experiment: resolved config, population, seats, module IDs."""

    exp: ExperimentConfig
    population: Population
    env_config: dict
    ego_agent: str
    partner_agent: str
    train: list[PartnerEntry]

    @property
    def head_ids(self) -> list[str]:
        """The ego heads being trained (one per training partner; one for BaselineAgg)."""
        return [AGG_HEAD_ID] if method(self.exp.method).single_head else [ego_id(e.name) for e in self.train]

    def head_for(self, partner_name: str) -> str:
        """The ego head that plays with `partner_name` (the shared head for single-network methods)."""
        return AGG_HEAD_ID if method(self.exp.method).single_head else ego_id(partner_name)


def resolve(exp: ExperimentConfig) -> EgoSetup:
    """Load the population, check it fits the game, and fill in the game's defaults."""
    pop = partners.get(exp.population)
    return setup_for(exp, pop, pop.entries("train"))


def setup_for(exp: ExperimentConfig, pop: Population, train: list[PartnerEntry]) -> EgoSetup:
    """The setup training the ego of `exp` against the partners `train` of `pop`."""
    if exp.env is not None and exp.env != pop.env:
        raise ValueError(f"env {exp.env!r} does not match population {pop.name!r}, which is for {pop.env!r}")
    env_config = {**pop.env_config, **exp.env_config}
    probe = envs.make(pop.env, **env_config)
    if len(probe.possible_agents) != 2 or pop.partner_agent not in probe.possible_agents:
        raise ValueError(
            f"population {pop.name!r}: partner_agent {pop.partner_agent!r} must be one of the game's two agents "
            f"{probe.possible_agents}"
        )
    if not train:
        raise ValueError(f"population {pop.name!r} has no partners to train with")
    ego_agent = next(a for a in probe.possible_agents if a != pop.partner_agent)
    _check_mapping(exp, [e.name for e in train])
    return EgoSetup(exp.resolve(pop.env), pop, env_config, ego_agent, pop.partner_agent, train)


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
