"""The marginal regulariser: known answers by hand, lam = 0 is PPO, and its place in the loss."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch

from rllib_conv.learners.marginal_learner import MARGINAL_REG_KEY
from rllib_conv.learners.ppo_loss import ppo_loss
from rllib_conv.learners.regulariser import marginal_distance
from rllib_conv.modules.multi import TASK_ID, replica_id
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.training.algorithm import Replica
from rllib_conv.training.evaluate import head_probs, task_probs
from rllib_conv.training.replica_export import replica_module
from tests.helpers import bandit_setup, build_learner, hand_batch


def test_marginal_distance_by_hand() -> None:
    # Row 1: task (0.5, 0.25, 0.25); heads (0.7, 0.2, 0.1) and (0.1, 0.6, 0.3) -> mean (0.4, 0.4, 0.2)
    #        |0.5-0.4| + |0.25-0.4| + |0.25-0.2| = 0.1 + 0.15 + 0.05 = 0.30
    # Row 2: task (1/3, 1/3, 1/3); heads (0.2, 0.2, 0.6) and (0.6, 0.2, 0.2) -> mean (0.4, 0.2, 0.4)
    #        1/15 + 2/15 + 1/15 = 4/15
    task = torch.log(torch.tensor([[0.5, 0.25, 0.25], [1 / 3, 1 / 3, 1 / 3]]))
    h1 = torch.log(torch.tensor([[0.7, 0.2, 0.1], [0.2, 0.2, 0.6]]))
    h2 = torch.log(torch.tensor([[0.1, 0.6, 0.3], [0.6, 0.2, 0.2]]))
    assert marginal_distance(task, torch.stack([h1, h2])).item() == pytest.approx((0.30 + 4 / 15) / 2, abs=1e-6)
    # The task module matching the mean policy exactly costs nothing.
    assert marginal_distance(torch.log(torch.tensor([[0.4, 0.4, 0.2]])), torch.stack([h1[:1], h2[:1]])).item() == pytest.approx(
        0.0, abs=1e-6
    )
    # Per replica ([K, ...] in, [K] out), padding rows left out: replica 1 is replica 0 with a padded row.
    stacked = marginal_distance(
        torch.stack([task, task]), torch.stack([torch.stack([h1, h2])] * 2), torch.tensor([[True, True], [True, False]])
    )
    assert stacked.tolist() == pytest.approx([(0.30 + 4 / 15) / 2, 0.30], abs=1e-6)


def test_masked_actions_are_excluded_from_the_distance() -> None:
    # An illegal action gets the float minimum as its logit: zero probability everywhere.
    lowest = torch.finfo(torch.float32).min
    task = torch.tensor([[0.0, 0.0, lowest]])
    head = torch.tensor([[np.log(3.0), 0.0, lowest]])  # (0.75, 0.25, 0)
    assert marginal_distance(task, head[None]).item() == pytest.approx(0.5, abs=1e-6)


def test_regulariser_term_in_the_learner_loss_equals_lam_times_d() -> None:
    setup = bandit_setup(lam=0.5)
    learner = build_learner(setup)
    heads = learner.module.head_ids()
    batch = hand_batch(heads)
    losses = learner.compute_losses(fwd_out=learner.module.forward_train(batch), batch=batch)
    assert set(losses) == set(heads) | {MARGINAL_REG_KEY}
    # D by hand from the ego's distributions on the same states, read from its plain modules.
    plain = replica_module(learner.module, 0, Replica(setup))
    obs = np.concatenate([batch[h]["obs"]["observations"].numpy() for h in heads])
    mean_policy = np.mean([head_probs(plain, h, obs) for h in setup.head_ids], axis=0)
    d = np.abs(task_probs(plain, obs) - mean_policy).sum(axis=1).mean()
    assert losses[MARGINAL_REG_KEY].item() == pytest.approx(0.5 * d, rel=1e-5)


def test_lam_zero_is_exactly_ppo() -> None:
    learner = build_learner(bandit_setup(lam=0.0))
    heads = learner.module.head_ids()
    batch = hand_batch(heads, seed=3)
    ours = learner.compute_losses(fwd_out=learner.module.forward_train(batch), batch=batch)
    assert set(ours) == set(heads)  # no extra term
    # Plain PPO on each head's own forward pass (no batched task forward, no regulariser).
    per_module = {h: learner.module[h].forward_train(batch[h]) for h in heads}
    ppo = PPOTorchLearner.compute_losses(learner, fwd_out=per_module, batch=batch)
    for h in heads:
        assert ours[h].item() == pytest.approx(ppo[h].item(), abs=1e-6)


def test_batched_train_forward_matches_each_heads_own_forward() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    heads = learner.module.head_ids()
    batch = hand_batch(heads, seed=5)
    batched = learner.module.forward_train(batch)
    assert set(batched) == set(heads) | {STACK_ID}
    for h in heads:
        single = learner.module[h].forward_train(batch[h])
        torch.testing.assert_close(batched[h]["action_dist_inputs"], single["action_dist_inputs"])
        torch.testing.assert_close(
            learner.module[h].compute_values(batch[h], batched[h]["embeddings"]), learner.module[h].compute_values(batch[h])
        )


@pytest.mark.parametrize("overrides", [{"lam": 0.0}, {"method": "no_task_logits"}])
def test_own_heads_forward_gives_the_all_heads_forwards_own_logits_and_values(overrides: dict) -> None:
    """Without a regulariser the learner runs each head on its own rows only: the same logits and values."""
    learner = build_learner([Replica(bandit_setup(**overrides, seed=s)) for s in (0, 1)])
    assert not learner.loss_reads_all_heads
    learner.module.stack.few_situations = False  # the per-row forward (the bandit's default runs per situation)
    _, obs, mask, valid, _ = learner.module.stack_batch(hand_batch(learner.module.head_ids(), rows=5, seed=2))
    valid[1, 2, 3:] = False  # a replica head with fewer rows than the others
    full = learner.module.forward_stacked(obs, mask, valid)
    own = learner.module.forward_stacked(obs, mask, valid, all_heads=False)
    assert own.all_logits is None and own.head_out is None and full.all_logits is not None
    torch.testing.assert_close(own.logits, full.logits)
    torch.testing.assert_close(own.values, full.values)


@pytest.mark.parametrize("overrides", [{"lam": 0.5, "head_l2": 0.1}, {"method": "no_task_logits"}, {"method": "oracle"}])
def test_the_forward_per_situation_gives_the_per_row_numbers_and_gradients(overrides: dict) -> None:
    """The bandit's training forward on its distinct contexts alone: the per-row forward's logits, values, D, H and gradients."""
    learner = build_learner([Replica(bandit_setup(**overrides, seed=s)) for s in (0, 1)])
    stack = learner.module.stack
    assert stack.few_situations
    batch = hand_batch(learner.module.head_ids(), rows=9, seed=6)
    batch[next(iter(batch))][Columns.OBS]["action_mask"][0, 3] = 0.0  # one row's mask differs: a situation of its own
    _, obs, mask, valid, _ = learner.module.stack_batch(batch)
    valid[1, 0, 5:] = False  # padding rows count for nothing
    results = {}
    for few in (True, False):
        stack.few_situations = few
        out = learner.module.forward_stacked(obs, mask, valid)
        terms = learner.stack_terms(out)
        ppo = ppo_loss(
            out.logits,
            out.values,
            torch.zeros_like(valid, dtype=torch.long),
            {
                Columns.ACTION_LOGP: torch.zeros(valid.shape),
                Postprocessing.ADVANTAGES: torch.ones(valid.shape),
                Postprocessing.VALUE_TARGETS: torch.ones(valid.shape),
            },
            valid=valid,
            clip_param=0.2,
            vf_loss_coeff=1.0,
            vf_clip_param=10.0,
            entropy_coeff=0.01,
        )
        total = ppo.total.sum() + sum(learner.stack_loss(terms).values())
        grads = torch.autograd.grad(total, [p for p in stack.parameters() if p.requires_grad], allow_unused=True)
        results[few] = (out, terms, grads)
    (few_out, few_terms, few_grads), (row_out, row_terms, row_grads) = results[True], results[False]
    assert few_out.all_logits.shape[2] < row_out.all_logits.shape[2]  # fewer situations than rows
    rows = valid.unsqueeze(-1)
    torch.testing.assert_close(few_out.logits * rows, row_out.logits * rows)
    torch.testing.assert_close(few_out.values * valid, row_out.values * valid)
    for key in few_terms:
        torch.testing.assert_close(few_terms[key], row_terms[key])
    for a, b in zip(few_grads, row_grads):
        assert (a is None) == (b is None)
        if a is not None:
            torch.testing.assert_close(a, b, rtol=1e-4, atol=1e-6)


def test_lam_zero_still_logs_the_regulariser_from_the_last_minibatch() -> None:
    learner = build_learner(bandit_setup(lam=0.0))
    batch = hand_batch(learner.module.head_ids(), rows=8, seed=4)
    mab = MultiAgentBatch({mid: SampleBatch(cols) for mid, cols in batch.items()}, env_steps=8 * len(batch))
    metrics = learner.update(batch=mab, num_epochs=2, minibatch_size=4, shuffle_batch_per_epoch=True, timesteps={})
    reg = metrics[replica_id(TASK_ID, 0)][MARGINAL_REG_KEY]
    assert 0.0 < reg.peek() <= 2.0  # D of random nets: positive, at most 2


@pytest.mark.parametrize(
    "overrides", [{"lam": 0.5}, {"method": "agg"}, {"method": "no_task_logits"}, {"method": "oracle"}, {"model": {"z_dim": 5}}]
)
def test_the_stack_plays_as_its_plain_modules(overrides: dict) -> None:
    """A replica's heads in the stack give the logits and values of the plain modules it exports, for every method."""
    setup = bandit_setup(**overrides)
    learner = build_learner(setup)
    plain = replica_module(learner.module, 0, Replica(setup))
    batch = hand_batch(learner.module.head_ids(), seed=2)
    for view_id, plain_id in zip(learner.module.head_ids(), setup.head_ids):
        obs = batch[view_id]["obs"]
        torch.testing.assert_close(
            learner.module[view_id].forward_train(batch[view_id])["action_dist_inputs"],
            plain[plain_id].forward_train({"obs": obs})["action_dist_inputs"],
        )
        torch.testing.assert_close(
            learner.module[view_id].compute_values(batch[view_id]), plain[plain_id].compute_values({"obs": obs})
        )
