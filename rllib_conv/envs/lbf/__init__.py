"""Level-Based Foraging: its env (`env.py`) over the `lbforaging` package, its observation layout and its record.

Needs the optional extra: `pip install rllib-conv[lbf]`. The first game here with more than two
players (2-4); its heuristic partners H1-H4 are `rllib_conv.partners.lbf`.
"""

from rllib_conv.envs.lbf.env import HORIZON, MAX_PLAYERS, MIN_PLAYERS, LBFEnv
from rllib_conv.envs.lbf.observation import (
    ACTION_NAMES,
    EAST,
    LOAD,
    NONE,
    NORTH,
    NUM_ACTIONS,
    SOUTH,
    WEST,
    SeenState,
    observation_size,
    read_observation,
)

__all__ = [
    "ACTION_NAMES",
    "EAST",
    "HORIZON",
    "LOAD",
    "MAX_PLAYERS",
    "MIN_PLAYERS",
    "NONE",
    "NORTH",
    "NUM_ACTIONS",
    "SOUTH",
    "WEST",
    "LBFEnv",
    "SeenState",
    "observation_size",
    "read_observation",
]
