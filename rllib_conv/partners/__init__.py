"""Fixed partners: the `Partner` interface, scripted partners per game, and populations.

Importing this package registers every built-in partner kind and population.
"""

from rllib_conv.partners import bandit, blocks, builtin, hanabi, trained  # noqa: F401  (registers kinds and populations)
from rllib_conv.partners.base import Partner
from rllib_conv.partners.kinds import kinds, partner_from_spec, register_kind
from rllib_conv.partners.play import play_episodes
from rllib_conv.partners.population import (
    PartnerEntry,
    Population,
    from_partners,
    get,
    names,
    register_builtin,
)

__all__ = [
    "Partner",
    "PartnerEntry",
    "Population",
    "from_partners",
    "get",
    "kinds",
    "names",
    "partner_from_spec",
    "play_episodes",
    "register_builtin",
    "register_kind",
]
