"""The task module's weights exist once (in the stack), each part gets one optimizer step per minibatch, and freezing freezes."""

from __future__ import annotations

import pytest
import torch
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch

from rllib_conv.modules import FixedPartnerModule
from rllib_conv.modules.packed.stacked_multi import STACK_ID, HeadView
from tests.helpers import bandit_setup, build_learner, hand_batch, head_weights, task_weights

LR = 3e-4


def optimizer_param_owners(learner) -> dict[int, list[str]]:
    """id(parameter) -> the optimizers (by name) that hold it."""
    owners: dict[int, list[str]] = {}
    for names in learner._module_optimizers.values():
        for name in names:
            for group in learner._named_optimizers[name].param_groups:
                for p in group["params"]:
                    owners.setdefault(id(p), []).append(name)
    return owners


def one_update(learner, seed: int = 0) -> None:
    """One PPO update (one epoch, one minibatch per head) of the learner's own loop on a hand-made batch."""
    batch = hand_batch(learner.module.head_ids(), seed=seed)
    mab = MultiAgentBatch({mid: SampleBatch(cols) for mid, cols in batch.items()}, env_steps=6 * len(batch))
    learner.update(batch=mab, num_epochs=1, minibatch_size=6, timesteps={})


def test_task_parameters_are_in_exactly_one_optimizer() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    owners = optimizer_param_owners(learner)
    stack = learner.module[STACK_ID]
    task, heads = stack.task_parameters(), stack.head_parameters()
    assert task and heads and not {id(p) for p in task} & {id(p) for p in heads}
    assert all(len(owners[id(p)]) == 1 for p in [*task, *heads])
    assert {owners[id(p)][0] for p in task}.isdisjoint({owners[id(p)][0] for p in heads})
    for mid, module in learner.module._rl_modules.items():
        if isinstance(module, (HeadView, FixedPartnerModule)):  # views and fixed partners hold no weights of their own
            assert not learner._module_optimizers.get(mid) and not list(getattr(module, "parameters", list)())
    assert set(learner._module_optimizers) == {STACK_ID}


def test_one_update_steps_the_task_module_once() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    before = task_weights(learner)
    one_update(learner)
    # Adam's first step moves each parameter by at most lr (about lr where the gradient is
    # not tiny); four steps, one per head's loss, would move some by up to 4 lr.
    moved = torch.cat([(v - before[k]).abs().flatten() for k, v in task_weights(learner).items()])
    assert LR * 0.9 <= moved.max().item() <= LR * 1.001


@pytest.mark.parametrize("freeze", [["task"], ["heads"]])
def test_frozen_parts_do_not_change(freeze: list[str]) -> None:
    learner = build_learner(bandit_setup(lam=0.5, freeze=freeze))
    stack, head = learner.module[STACK_ID], learner.module.head_ids()[0]
    frozen_params = stack.task_parameters() if freeze == ["task"] else stack.head_parameters()
    assert not any(p.requires_grad for p in frozen_params)

    def weights() -> tuple[dict, dict]:
        task, heads = task_weights(learner), head_weights(learner, head)
        return (task, heads) if freeze == ["task"] else (heads, task)

    before_frozen, before_trained = weights()
    for seed in range(3):
        one_update(learner, seed)
    after_frozen, after_trained = weights()
    assert all(torch.equal(v, before_frozen[k]) for k, v in after_frozen.items())
    assert any(not torch.equal(v, before_trained[k]) for k, v in after_trained.items())


def test_head_views_read_the_learners_stack() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    stack = learner.module[STACK_ID]
    for mid in learner.module.head_ids():
        view = learner.module[mid]
        assert view.stack is stack and not list(view.parameters())
    assert [learner.module[mid].head for mid in learner.module.head_ids()] == list(range(stack.heads))


@pytest.mark.parametrize("scale", [0.1, 0.0])
def test_z_layers_learn_at_their_own_rate(scale: float) -> None:
    learner = build_learner(bandit_setup(lam=0.5, z_lr_scale=scale))
    before = task_weights(learner)
    one_update(learner)
    after = task_weights(learner)

    def largest_move(prefix: str) -> float:
        return max((v - before[k]).abs().max().item() for k, v in after.items() if k.startswith(prefix))

    # Adam's first step moves each parameter by at most its learning rate, about that much
    # where the gradient is not tiny: lr x scale for the z layers, lr for the task logits.
    assert LR * scale * 0.9 <= largest_move("pi_tower") <= LR * scale * 1.001
    assert LR * 0.9 <= largest_move("pi_out") <= LR * 1.001
    z = learner.module[STACK_ID].task_parameters(z_only=True)
    assert all(p.requires_grad == (scale > 0) for p in z)
