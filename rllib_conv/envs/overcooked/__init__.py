"""Overcooked-AI: its env (`env.py`) over the `overcooked` package's MDP, our grid encoding, the shaping schedule, hidden utilities and its record.

Needs the optional extra: `pip install rllib-conv[overcooked]`. The env's names are handed on
here, so `rllib_conv.envs.overcooked` is the game as importers know it.
"""

from rllib_conv.envs.overcooked.encoding import CHANNEL, CHANNELS, NUM_CHANNELS, GridEncoder
from rllib_conv.envs.overcooked.env import (
    ACTION_NAMES,
    ACTIONS,
    CLASSIC_LAYOUTS,
    EAST,
    HORIZON,
    INTERACT,
    NORTH,
    NUM_ACTIONS,
    SOUTH,
    STAY,
    WEST,
    OvercookedEnv,
    action_index,
    build_mdp,
    layouts,
)
from rllib_conv.envs.overcooked.hidden_utility import EVENTS
from rllib_conv.envs.overcooked.shaping import shaping_factor

__all__ = [
    "ACTION_NAMES",
    "ACTIONS",
    "CHANNEL",
    "CHANNELS",
    "CLASSIC_LAYOUTS",
    "EAST",
    "EVENTS",
    "HORIZON",
    "INTERACT",
    "NORTH",
    "NUM_ACTIONS",
    "NUM_CHANNELS",
    "SOUTH",
    "STAY",
    "WEST",
    "GridEncoder",
    "OvercookedEnv",
    "action_index",
    "build_mdp",
    "layouts",
    "shaping_factor",
]
