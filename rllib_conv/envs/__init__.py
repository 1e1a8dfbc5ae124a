"""The paper's games as PettingZoo envs, behind a name registry.

`make(name, **config)` builds a registered env, `names()` lists them, and
`register(name, factory)` adds a user's own PettingZoo env (AEC or parallel) under a
name that configs and the CLI then accept (`register_convention_key` says which of its
situations carry separate conventions, `register_best_response` how an ego plans against
a partner model). `to_rllib(name)` exposes any registered
env to RLlib/Tune as a `MultiAgentEnv`.
"""

from rllib_conv.envs.bandit import CollaborativeBanditEnv
from rllib_conv.envs.best_response import best_response, register_best_response
from rllib_conv.envs.blocks import BlockPlacingEnv
from rllib_conv.envs.blocks_best_response import BlocksBestResponse
from rllib_conv.envs.convention_keys import convention_key, register_convention_key
from rllib_conv.envs.hanabi import HanabiEnv
from rllib_conv.envs.registry import make, names, register

register("bandit", CollaborativeBanditEnv)
register("blocks", BlockPlacingEnv)
register("hanabi", HanabiEnv)

__all__ = [
    "make", "names", "register", "convention_key", "register_convention_key", "best_response", "register_best_response",
    "CollaborativeBanditEnv", "BlockPlacingEnv", "BlocksBestResponse", "HanabiEnv",
]
