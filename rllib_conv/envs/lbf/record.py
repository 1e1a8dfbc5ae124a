"""Level-Based Foraging's record: its env and scripted partners; no oracle, key or exact best response yet."""

from __future__ import annotations

from rllib_conv.envs.game import GameRecord
from rllib_conv.envs.lbf.env import LBFEnv

LBF = GameRecord(
    name="lbf",
    env=LBFEnv,
    title="Level-Based Foraging",
    # No training defaults of its own yet: the fallback's (64 units, 256-step rollouts per partner) until a
    # trained ego shows what this game needs.
    max_score=1.0,  # the team's normalised reward: every food collected
    partners=("rllib_conv.partners.lbf",),
)
