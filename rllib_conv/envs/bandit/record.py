"""The collaborative contextual bandit's record: the paper's settings and everything the stages ask of it."""

from __future__ import annotations

from rllib_conv.envs.bandit.best_response import bandit_best_response_return
from rllib_conv.envs.bandit.env import CollaborativeBanditEnv
from rllib_conv.envs.bandit.exact import bandit_exact_return
from rllib_conv.envs.bandit.keys import bandit_context
from rllib_conv.envs.bandit.oracle import bandit_oracle, bandit_states
from rllib_conv.envs.defaults import AdaptDefaults, TrainingDefaults, ZeroShotDefaults
from rllib_conv.envs.game import GameRecord

BANDIT = GameRecord(
    name="bandit",
    env=CollaborativeBanditEnv,
    title="Collaborative contextual bandit",
    training=TrainingDefaults(hidden=30, rollout_per_partner=64, minibatch_size=16, num_epochs=20, timesteps=10_000),
    adaptation=AdaptDefaults(every=16, steps=240, minibatch_size=16, num_epochs=50),
    zeroshot=ZeroShotDefaults(head_steps=2_560, task_steps=10_000),
    new_task=True,
    oracle=bandit_oracle,
    states=bandit_states,
    convention_key=bandit_context,
    exact_return=bandit_exact_return,
    best_response_return=bandit_best_response_return,
    max_score=1.0,  # Sec. 4.1: "the maximum score ... is 1"
    partners=("rllib_conv.partners.bandit", "rllib_conv.partners.user_study"),
)
