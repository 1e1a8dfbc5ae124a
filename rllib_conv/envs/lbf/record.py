"""Level-Based Foraging's record: its env, budgets, scripted partners and seat views; no oracle, key or exact best response yet."""

from __future__ import annotations

from rllib_conv.envs.defaults import AdaptDefaults, TrainingDefaults
from rllib_conv.envs.game import GameRecord
from rllib_conv.envs.lbf.env import LBFEnv
from rllib_conv.envs.lbf.seat_view import lbf_seat_view

LBF = GameRecord(
    name="lbf",
    env=LBFEnv,
    title="Level-Based Foraging",
    # Not the paper's (it has no such game): measured here on `lbf-heuristics` (3 players, 4 training teams). With
    # these settings the egos of `reproduce lbf` collect, with their training teams, 0.42-0.47 of the food (ours,
    # lam 0.5), 0.53-0.57 (BaselineAgg), 0.38-0.41 (BaselineModular), 0.46-0.49 (MAML) at 200k env steps, 3 seeds;
    # a random ego with H1 and H2: 0.35; the heuristics among themselves 0.31-0.37. 500-step rollouts per team are
    # 10 to 20 episodes, so each update sees every team's whole episodes.
    training=TrainingDefaults(hidden=64, rollout_per_partner=500, minibatch_size=250, num_epochs=4, timesteps=200_000),
    # One update per 500 steps of the new team, for 20 updates; 50 episodes per point (a point's standard error
    # ~0.03), since 200 episodes of up to 50 steps each made evaluation most of the stage.
    adaptation=AdaptDefaults(every=500, steps=10_000, episodes=50),
    # With partial sight (`sight` < `size`) a partner sees food and players out of the ego's view; a setting of the
    # game, so the record says it for every setting: no adapter reads the partner's own observation here.
    partner_sees="the food and players in its view but out of the ego's (with sight < size)",
    # With full sight a partner's situation is rebuilt from the ego's own observation (the plastic adapter reads it).
    seat_view=lbf_seat_view,
    max_score=1.0,  # the team's normalised reward: every food collected
    partners=("rllib_conv.partners.lbf",),
)
