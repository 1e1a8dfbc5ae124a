"""Fixed partners: the `Partner` interface, scripted partners per game, and populations.

Importing this package registers every built-in partner kind and population: each game's
scripted kinds and populations from the modules its record names (`GameRecord.partners`),
so a new game adds none here; the trained-policy kind (torch, RLlib) loads on first use.
"""

import importlib

from rllib_conv import envs
from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import play_episodes
from rllib_conv.partners.kinds import kinds, partner_from_spec, register_kind
from rllib_conv.partners.population import (
    PartnerEntry,
    Population,
    from_partners,
    get,
    is_builtin,
    names,
    register_builtin,
)

for _game in envs.games():
    for _module in _game.partners:
        importlib.import_module(_module)

__all__ = [
    "Partner",
    "PartnerEntry",
    "Population",
    "from_partners",
    "get",
    "is_builtin",
    "kinds",
    "names",
    "partner_from_spec",
    "play_episodes",
    "register_builtin",
    "register_kind",
]
