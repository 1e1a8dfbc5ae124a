"""Hanabi through the Hanabi Learning Environment: its env (`env.py`) and record.

The env's names are handed on here, so `rllib_conv.envs.hanabi` is the game as importers know it.
"""

from rllib_conv.envs.hanabi.env import (
    ENV_NAME,
    MAX_COLORS,
    MAX_HAND_SIZE,
    MAX_RANKS,
    MAX_TOKENS,
    OBSERVATION_TYPES,
    HanabiConfig,
    HanabiEnv,
    HanabiMoveIds,
    card_count,
    card_knowledge_layout,
    cards_per_color,
    decode_card_knowledge,
)

__all__ = [
    "ENV_NAME",
    "MAX_COLORS",
    "MAX_HAND_SIZE",
    "MAX_RANKS",
    "MAX_TOKENS",
    "OBSERVATION_TYPES",
    "HanabiConfig",
    "HanabiEnv",
    "HanabiMoveIds",
    "card_count",
    "card_knowledge_layout",
    "cards_per_color",
    "decode_card_knowledge",
]
