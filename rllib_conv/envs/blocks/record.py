"""Block Placing's record: the paper's settings and everything the stages ask of it."""

from __future__ import annotations

from rllib_conv.envs.blocks.best_response import blocks_best_response, blocks_best_response_return
from rllib_conv.envs.blocks.env import BlockPlacingEnv
from rllib_conv.envs.blocks.exact import blocks_exact_return
from rllib_conv.envs.blocks.keys import blocks_observation
from rllib_conv.envs.blocks.oracle import blocks_canonical, blocks_oracle
from rllib_conv.envs.defaults import AdaptDefaults, TrainingDefaults, ZeroShotDefaults
from rllib_conv.envs.game import GameRecord

BLOCKS = GameRecord(
    name="blocks",
    env=BlockPlacingEnv,
    title="Block Placing",
    training=TrainingDefaults(hidden=80, rollout_per_partner=640, minibatch_size=160, num_epochs=5, timesteps=1_000_000),
    adaptation=AdaptDefaults(every=640, steps=25_600, minibatch_size=160, num_epochs=5),
    # Step 1 runs until the test heads have converged on the old task: ~19.5 of 20 by 300k
    # steps (at 100k, BaselineModular's heads, which learn the rules too, reach ~11.5).
    zeroshot=ZeroShotDefaults(head_steps=300_000, task_steps=400_000),
    new_task=True,
    oracle=blocks_oracle,
    canonical=blocks_canonical,
    convention_key=blocks_observation,
    best_response=blocks_best_response,
    exact_return=blocks_exact_return,
    best_response_return=blocks_best_response_return,
    max_score=20.0,  # Sec. 5: "a maximum of 20 points per game"
    partners=("rllib_conv.partners.blocks",),
)
