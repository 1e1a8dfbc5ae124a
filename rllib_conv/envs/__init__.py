"""The paper's games as PettingZoo envs, each one folder plus one record, behind a name registry.

A game is a folder (`bandit/`, `blocks/`, `hanabi/`: its env, oracle, convention key,
best response and `record.py`) and one `GameRecord` registered here. `game(name)` is a
game's record (what every layer asks instead of branching on a name), `make(name, **config)`
builds its env, `names()` lists them, `register_game(record)` adds one and `register(name,
factory)` adds a bare PettingZoo env (AEC or parallel). A game named by import path
(`"package.module:RECORD"`) is found in every process. `to_rllib(name)` exposes any
registered env to RLlib/Tune as a `MultiAgentEnv`. Overcooked (`overcooked/`) is registered
only where its optional extra, the `overcooked` package, is installed, and Level-Based
Foraging (`lbf/`, 2-4 players) only where `lbforaging` is; elsewhere `game(name)` says how
to install it.
"""

import importlib.util

from rllib_conv.envs.bandit import CollaborativeBanditEnv
from rllib_conv.envs.bandit.record import BANDIT
from rllib_conv.envs.best_response import best_response, best_response_return
from rllib_conv.envs.blocks import BlockPlacingEnv
from rllib_conv.envs.blocks.best_response import BlocksBestResponse
from rllib_conv.envs.blocks.record import BLOCKS
from rllib_conv.envs.convention_keys import convention_key
from rllib_conv.envs.game import GameRecord
from rllib_conv.envs.hanabi import HanabiEnv
from rllib_conv.envs.hanabi.record import HANABI
from rllib_conv.envs.registry import game, games, make, make_scored, names, register, register_game, register_missing

for _record in (BANDIT, BLOCKS, HANABI):
    register_game(_record, builtin=True)

if importlib.util.find_spec("overcooked") is not None:
    from rllib_conv.envs.overcooked.record import OVERCOOKED

    register_game(OVERCOOKED, builtin=True)
else:
    register_missing("overcooked", "pip install 'rllib-conv[overcooked]'")

if importlib.util.find_spec("lbforaging") is not None:
    from rllib_conv.envs.lbf.record import LBF

    register_game(LBF, builtin=True)
else:
    register_missing("lbf", "pip install 'rllib-conv[lbf]'")

__all__ = [
    "GameRecord",
    "game",
    "games",
    "make",
    "make_scored",
    "names",
    "register",
    "register_game",
    "convention_key",
    "best_response",
    "best_response_return",
    "CollaborativeBanditEnv",
    "BlockPlacingEnv",
    "BlocksBestResponse",
    "HanabiEnv",
]
