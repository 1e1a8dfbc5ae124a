"""The opt-in `ppo.precision: bfloat16` learner: matrix products round to bfloat16 under autocast, so the weights
differ from float32's, but by a small part of what the update moved them; weights and Adam stay float32."""

from __future__ import annotations

import numpy as np
import torch
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch

from rllib_conv.common import config_files
from rllib_conv.envs.replicated_game import ReplicatedGame
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.pipelines.selfplay import build_joint_config
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from tests.helpers import bandit_setup, build_learner, hand_batch, params_of
from tests.learners.test_fused_update import _update


def _apart(initial: dict, f32: dict, bf16: dict) -> tuple[float, float]:
    """(norm of float32's update, norm of bfloat16's distance from float32) over every weight."""
    moved = torch.cat([(f32[k] - initial[k]).flatten() for k in f32]).norm()
    apart = torch.cat([(bf16[k] - f32[k]).flatten() for k in f32]).norm()
    return float(moved), float(apart)


def test_bfloat16_stacked_learner_stays_near_float32_and_keeps_float32_weights() -> None:
    """Packed egos (the stacked minibatch loss)."""
    base = {"lam": 0.5}
    torch.manual_seed(0)
    f32 = _update(True, base, 3, 4, 10)
    torch.manual_seed(0)
    bf16 = _update(True, {**base, "ppo": {"precision": "bfloat16"}}, 3, 4, 10)
    torch.manual_seed(0)
    initial = params_of(build_learner(bandit_setup(**base)).module[STACK_ID])
    moved, apart = _apart(initial, f32, bf16)
    assert all(v.dtype == torch.float32 for v in bf16.values())
    assert 0 < apart < 0.2 * moved  # > 0: bfloat16 really ran


def _selfplay_weights(precision: str, update: bool = True) -> dict[str, torch.Tensor]:
    """Two bandit self-play pairs trained together (plain RLlib modules: the learner's plain epochs), after two updates."""
    raw = config_files.load("tune_configs/selfplay_bandit.yaml", [], schema=SelfPlayConfig)
    raw.update(
        {"train_pairs": 2, "test_pairs": 0, "model": {"hidden": 16}, "ppo": {**raw.get("ppo", {}), "precision": precision}}
    )
    config = build_joint_config(SelfPlayConfig.model_validate(raw).resolve())
    torch.manual_seed(0)
    learner = config.build_learner(env=ReplicatedGame(config.env_config))
    mids = sorted(learner.module.keys())
    np.random.seed(7)
    for i in range(2 if update else 0):
        batch = hand_batch(mids, rows=12, num_arms=8, seed=3 + i)
        mab = MultiAgentBatch({mid: SampleBatch(cols) for mid, cols in batch.items()}, env_steps=12 * len(batch))
        learner.update(batch=mab, num_epochs=3, minibatch_size=4, shuffle_batch_per_epoch=True, timesteps={})
    return {f"{mid}/{k}": v.detach().clone() for mid in mids for k, v in learner.module[mid].state_dict().items()}


def test_bfloat16_selfplay_learner_stays_near_float32_and_keeps_float32_weights() -> None:
    """Self-play seats (plain modules, the learner's plain epochs)."""
    f32, bf16 = _selfplay_weights("float32"), _selfplay_weights("bfloat16")
    moved, apart = _apart(_selfplay_weights("float32", update=False), f32, bf16)
    assert all(v.dtype == torch.float32 for v in bf16.values())
    assert 0 < apart < 0.2 * moved
