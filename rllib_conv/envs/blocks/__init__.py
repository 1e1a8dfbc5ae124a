"""Block Placing: its env (`env.py`), oracle, convention key, best response and record.

The env's names are handed on here, so `rllib_conv.envs.blocks` is the game as importers know it.
"""

from rllib_conv.envs.blocks.env import (
    ACTION_NAMES,
    BLUE,
    CELL_REWARD,
    EMPTY,
    GOALS,
    HIDDEN,
    NUM_ACTIONS,
    NUM_CELLS,
    NUM_MOVES,
    OBS_DIM,
    PASS,
    RED,
    REMOVE,
    BlockPlacingEnv,
    apply_move,
    block_cell,
    decode_observation,
    decode_observations,
    encode_observation,
    final_reward,
)

__all__ = [
    "ACTION_NAMES",
    "BLUE",
    "CELL_REWARD",
    "EMPTY",
    "GOALS",
    "HIDDEN",
    "NUM_ACTIONS",
    "NUM_CELLS",
    "NUM_MOVES",
    "OBS_DIM",
    "PASS",
    "RED",
    "REMOVE",
    "BlockPlacingEnv",
    "apply_move",
    "block_cell",
    "decode_observation",
    "decode_observations",
    "encode_observation",
    "final_reward",
]
