"""The head penalty (`head_l2`, not in the paper): known answers, its place in the loss, what it teaches."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rllib_conv.learners.head_penalty import head_size
from rllib_conv.learners.marginal_learner import HEAD_L2_KEY, MARGINAL_REG_KEY
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.training.algorithm import Replica
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.replica_export import replica_module
from tests.helpers import bandit_setup, build_learner, hand_batch


def test_head_size_by_hand() -> None:
    # Head 1, row 1: (1, 2, 3) -> centred (-1, 0, 1) -> 2.   Row 2: (5, 5, 5) -> 0 (a shift costs nothing).
    # Head 2, row 1: (0, 0, 3) -> centred (-1, -1, 2) -> 6.  Row 2: (-2, 0, 2) -> 8.
    outputs = torch.tensor([[[1.0, 2.0, 3.0], [5.0, 5.0, 5.0]], [[0.0, 0.0, 3.0], [-2.0, 0.0, 2.0]]])
    assert head_size(outputs).item() == pytest.approx((2 + 0 + 6 + 8) / 4)


def test_head_penalty_in_the_learner_loss_is_weight_times_size_of_the_heads_own_outputs() -> None:
    setup = bandit_setup(lam=0.5, head_l2=0.2)
    learner = build_learner(setup)
    heads = learner.module.head_ids()
    batch = hand_batch(heads, seed=4)
    losses = learner.compute_losses(fwd_out=learner.module.forward_train(batch), batch=batch)
    assert set(losses) == set(heads) | {MARGINAL_REG_KEY, HEAD_L2_KEY}
    # By hand: every head's own output on every state of the minibatch, centred over actions.
    obs = torch.cat([batch[h]["obs"]["observations"] for h in heads])
    plain = replica_module(learner.module, 0, Replica(setup))
    with torch.no_grad():
        z = plain.task.policy(obs, None).z
        outputs = np.stack([plain[h].pi(z).numpy() for h in setup.head_ids])
    centred = outputs - outputs.mean(axis=-1, keepdims=True)
    assert losses[HEAD_L2_KEY].item() == pytest.approx(0.2 * (centred**2).sum(axis=-1).mean(), rel=1e-5)
    # Its gradient reaches the heads (and z), never the task module's logits layer.
    losses[HEAD_L2_KEY].backward()
    stack = learner.module[STACK_ID]
    assert stack.head_parameters()[0].grad.abs().sum() > 0 and stack.task_parameters(z_only=True)[0].grad.abs().sum() > 0
    assert stack.task__pi_out_0__weight.grad is None


def test_head_penalty_is_for_modular_heads_only() -> None:
    ExperimentConfig(population="blocks-perm", method="modular", head_l2=0.01)
    for method in ("agg", "no_task_logits", "oracle", "maml"):
        with pytest.raises(ValueError, match=f"head_l2 must be 0 for method '{method}'"):
            ExperimentConfig(population="blocks-perm", method=method, head_l2=0.01)
