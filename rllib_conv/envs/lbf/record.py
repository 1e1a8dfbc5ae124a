"""Level-Based Foraging's record: its env, scripted partners and seat views; no oracle, key or exact best response yet."""

from __future__ import annotations

from rllib_conv.envs.game import GameRecord
from rllib_conv.envs.lbf.env import LBFEnv
from rllib_conv.envs.lbf.seat_view import lbf_seat_view

LBF = GameRecord(
    name="lbf",
    env=LBFEnv,
    title="Level-Based Foraging",
    # No training defaults of its own yet: the fallback's (64 units, 256-step rollouts per partner) until a
    # trained ego shows what this game needs.
    # With partial sight (`sight` < `size`) a partner sees food and players out of the ego's view; a setting of the
    # game, so the record says it for every setting: no adapter reads the partner's own observation here.
    partner_sees="the food and players in its view but out of the ego's (with sight < size)",
    # With full sight a partner's situation is rebuilt from the ego's own observation (the plastic adapter reads it).
    seat_view=lbf_seat_view,
    max_score=1.0,  # the team's normalised reward: every food collected
    partners=("rllib_conv.partners.lbf",),
)
