"""Blocks' convention key: each distinct observation of a partner is a situation.

A partner's observation is all it acts on (the goal hidden from P2, the working grid, the
move number). The ego's own observations are other situations: it answers by planning
against the partner's predicted moves (`envs/blocks/best_response.py`), not by looking a
situation up.
"""

from __future__ import annotations

import numpy as np

from rllib_conv.envs.blocks.env import NUM_CELLS, NUM_MOVES, decode_observation


def blocks_observation(observation: np.ndarray) -> int:
    """Blocks: the observation as one number (the goal as seen, the working grid, the move)."""
    seen = decode_observation(observation)
    goal = int(np.dot(seen["goal"], 4 ** np.arange(NUM_CELLS)))
    grid = int(np.dot(seen["grid"], 3 ** np.arange(NUM_CELLS)))
    return (goal * 3**NUM_CELLS + grid) * (NUM_MOVES + 1) + seen["move"]
