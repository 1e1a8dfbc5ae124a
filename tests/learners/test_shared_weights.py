"""The shared task module's weights exist once, are stepped once per update, and freezing freezes."""

from __future__ import annotations

import pytest
import torch

from rllib_conv.modules import TASK_ID, FixedPartnerModule, PartnerHeadModule
from tests.helpers import bandit_setup, build_learner, hand_batch, params_of

LR = 3e-4


def optimizer_param_owners(learner) -> dict[int, list[str]]:
    """id(parameter) -> the modules whose optimizers hold it."""
    owners: dict[int, list[str]] = {}
    for mid, names in learner._module_optimizers.items():
        for name in names:
            for group in learner._named_optimizers[name].param_groups:
                for p in group["params"]:
                    owners.setdefault(id(p), []).append(mid)
    return owners


def test_task_parameters_are_in_exactly_one_optimizer() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    owners = optimizer_param_owners(learner)
    task_params = list(learner.module[TASK_ID].parameters())
    assert task_params and all(owners[id(p)] == [TASK_ID] for p in task_params)
    for mid in learner.module.head_ids():
        head_params = list(learner.module[mid].parameters())
        # A head's parameters are its own: the task module is referenced, not registered.
        assert not {id(p) for p in head_params} & {id(p) for p in task_params}
        assert all(owners[id(p)] == [mid] for p in head_params)
    for mid, module in learner.module._rl_modules.items():
        if isinstance(module, FixedPartnerModule):
            assert not learner._module_optimizers.get(mid) and not list(getattr(module, "parameters", list)())
    assert all(len(mods) == 1 for mods in owners.values())


def test_one_update_steps_the_task_module_once() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    steps: dict[str, int] = {}
    for mid, names in learner._module_optimizers.items():
        for name in names:
            opt = learner._named_optimizers[name]
            original = opt.step

            def counted(*args, _mid=mid, _orig=original, **kwargs):
                steps[_mid] = steps.get(_mid, 0) + 1
                return _orig(*args, **kwargs)

            opt.step = counted
    before = params_of(learner.module[TASK_ID])
    learner._update(hand_batch(learner.module.head_ids()))
    assert steps == {TASK_ID: 1, **{h: 1 for h in learner.module.head_ids()}}
    # Adam's first step moves each parameter by at most lr (about lr where the gradient is
    # not tiny); four steps, one per head, would move some by up to 4 lr.
    moved = torch.cat([(p.detach() - before[k]).abs().flatten() for k, p in learner.module[TASK_ID].named_parameters()])
    assert moved.max().item() <= LR * 1.001
    assert moved.max().item() >= LR * 0.9


@pytest.mark.parametrize(("freeze", "frozen_kind"), [(["task"], "task"), (["heads"], "heads")])
def test_frozen_parts_do_not_change(freeze: list[str], frozen_kind: str) -> None:
    learner = build_learner(bandit_setup(lam=0.5, freeze=freeze))
    heads = learner.module.head_ids()
    task, head = learner.module[TASK_ID], learner.module[heads[0]]
    frozen, trained = (task, head) if frozen_kind == "task" else (head, task)
    assert not any(p.requires_grad for p in frozen.parameters())
    frozen_ids = [TASK_ID] if frozen_kind == "task" else heads
    assert not any(learner._module_optimizers.get(mid) for mid in frozen_ids)
    before_frozen, before_trained = params_of(frozen), params_of(trained)
    for seed in range(3):
        learner._update(hand_batch(heads, seed=seed))
    assert all(torch.equal(p, before_frozen[k]) for k, p in frozen.named_parameters())
    assert any(not torch.equal(p, before_trained[k]) for k, p in trained.named_parameters())


def test_heads_share_the_learners_task_module() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    task = learner.module[TASK_ID]
    for mid in learner.module.head_ids():
        head = learner.module[mid]
        assert isinstance(head, PartnerHeadModule) and head.task is task
    assert "task" not in dict(learner.module[learner.module.head_ids()[0]].named_children())


@pytest.mark.parametrize("scale", [0.1, 0.0])
def test_z_layers_learn_at_their_own_rate(scale: float) -> None:
    learner = build_learner(bandit_setup(lam=0.5, z_lr_scale=scale))
    task = learner.module[TASK_ID]
    before = params_of(task)
    learner._update(hand_batch(learner.module.head_ids()))

    def largest_move(prefix: str) -> float:
        return max((p.detach() - before[k]).abs().max().item() for k, p in task.named_parameters() if k.startswith(prefix))

    # Adam's first step moves each parameter by at most its learning rate, about that much
    # where the gradient is not tiny: lr x scale for the z layers, lr for the task logits.
    assert LR * scale * 0.9 <= largest_move("pi_tower") <= LR * scale * 1.001
    assert LR * 0.9 <= largest_move("pi_out") <= LR * 1.001
    assert all(p.requires_grad == (scale > 0) for p in task.pi_tower.parameters())
