"""Hanabi's record: the paper's settings (no oracle, no new task, no convention key); the partner sees the ego's hand."""

from __future__ import annotations

from rllib_conv.envs.defaults import AdaptDefaults, TrainingDefaults
from rllib_conv.envs.game import GameRecord
from rllib_conv.envs.hanabi.env import HanabiEnv

HANABI = GameRecord(
    name="hanabi",
    env=HanabiEnv,
    title="Hanabi",
    training=TrainingDefaults(hidden=500, rollout_per_partner=640, minibatch_size=160, num_epochs=5, timesteps=500_000),
    adaptation=AdaptDefaults(every=640, steps=25_600, minibatch_size=160, num_epochs=5),
    max_score=5.0,  # Sec. 5, Hanabi: "for a maximum score of 5"
    # Each seat sees the other's cards, never its own: judging the partner's moves in the partner's situation
    # would read the ego's hidden hand.
    partner_sees="the ego's own hand",
    partners=("rllib_conv.partners.hanabi",),
)
