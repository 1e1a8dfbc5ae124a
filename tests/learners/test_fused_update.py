"""The learner's own minibatch loop gives RLlib's weights: same minibatches, same loss, same clipping, same Adam.

RLlib's loop (`PPOTorchLearner.update`, called past the learner's override) is the reference; training never runs it.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch

from rllib_conv.learners.packed.minibatches import CyclicMinibatchPlan, ModulePermuters
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from tests.helpers import bandit_setup, build_learner, hand_batch, params_of


def _update(
    fused: bool, setup_overrides: dict, epochs: int, minibatch: int, rows: int, seed: int = 7
) -> dict[str, dict[str, torch.Tensor]]:
    learner = build_learner(bandit_setup(**setup_overrides))
    update = learner.update if fused else lambda **kw: PPOTorchLearner.update(learner, **kw)  # RLlib's own loop, the reference
    # Shuffles from NumPy's global RNG, as RLlib's loop draws them (per-module generators are tested below).
    learner.config.learner_config_dict["shuffle_seeds"] = {}
    learner.__dict__.pop("settings", None)  # re-read the settings just changed
    np.random.seed(seed)  # RLlib's shuffles draw from NumPy's global RNG; the plan draws the same
    for i in range(2):  # twice: Adam's second step uses the first one's moments
        # A fresh batch per update, as in training: RLlib's loop shuffles its batch in place.
        batch = hand_batch(learner.module.head_ids(), rows=rows, seed=3 + i)
        mab = MultiAgentBatch({mid: SampleBatch(cols) for mid, cols in batch.items()}, env_steps=rows * len(batch))
        update(batch=mab, num_epochs=epochs, minibatch_size=minibatch, shuffle_batch_per_epoch=True, timesteps={})
    return params_of(learner.module[STACK_ID])


@pytest.mark.parametrize(
    ("overrides", "epochs", "minibatch", "rows"),
    [
        ({"lam": 0.5}, 3, 4, 10),  # minibatches that wrap around the end of a module's rows
        ({"lam": 0.0, "head_l2": 0.05}, 2, 5, 5),  # one minibatch per epoch, head penalty on
        ({"lam": 0.5, "z_lr_scale": 0.5}, 2, 3, 7),  # two optimizers for the task module
        ({"method": "no_task_logits"}, 2, 4, 8),  # task logits unused: their layer gets no gradient
    ],
)
def test_fused_update_gives_rllibs_weights(overrides, epochs, minibatch, rows) -> None:
    torch.manual_seed(0)
    rllib = _update(False, overrides, epochs, minibatch, rows)
    torch.manual_seed(0)
    fused = _update(True, overrides, epochs, minibatch, rows)
    torch.manual_seed(0)
    initial = params_of(build_learner(bandit_setup(**overrides)).module[STACK_ID])
    for name, value in rllib.items():
        torch.testing.assert_close(fused[name], value, rtol=1e-5, atol=1e-6, msg=name)
    # The updates did something: the task module and the heads moved away from their initial weights.
    for kind in ("task__", "head_pi__"):
        assert any(not torch.allclose(initial[k], v) for k, v in rllib.items() if k.startswith(kind))


def test_plan_matches_rllibs_cyclic_iterator_row_for_row() -> None:
    from ray.rllib.utils.minibatch_utils import MiniBatchCyclicIterator

    sizes = {"a": 10, "b": 7}
    batch = MultiAgentBatch({mid: SampleBatch({"row": np.arange(n)}) for mid, n in sizes.items()}, env_steps=17)
    np.random.seed(1)
    theirs = [
        {mid: mb.policy_batches[mid]["row"].tolist() for mid in sizes}
        for mb in MiniBatchCyclicIterator(batch, num_epochs=3, minibatch_size=4, shuffle_batch_per_epoch=True)
    ]
    np.random.seed(1)
    ours = [{mid: rows.tolist() for mid, rows in mb.items()} for mb in CyclicMinibatchPlan(sizes, 4, 3, shuffle=True)]
    assert ours == theirs and len(ours) >= 3 * 10 // 4


def test_each_epoch_of_a_module_uses_every_row_once_with_per_module_generators() -> None:
    plan = CyclicMinibatchPlan({"a": 8, "b": 8}, 4, 3, shuffle=True, permute=ModulePermuters({"a": 1, "b": 2}))
    batches = list(plan)
    assert len(batches) == 6
    for mid in ("a", "b"):
        rows = torch.cat([b[mid] for b in batches]).view(3, 8)
        assert all(sorted(epoch.tolist()) == list(range(8)) for epoch in rows)
    # Module a's order depends on its own generator only: a plan without b shuffles a identically.
    alone = list(CyclicMinibatchPlan({"a": 8}, 4, 3, shuffle=True, permute=ModulePermuters({"a": 1})))
    assert [b["a"].tolist() for b in alone] == [b["a"].tolist() for b in batches]


def test_an_old_fused_update_switch_is_ignored() -> None:
    # Algorithm checkpoints written while RLlib's loop could still be chosen carry the switch.
    learner = build_learner(bandit_setup(lam=0.5))
    learner.config.learner_config_dict["fused_update"] = False
    learner.__dict__.pop("settings", None)
    assert learner.settings.lam == 0.5 and not hasattr(learner.settings, "fused_update")


def test_the_update_refuses_what_only_remote_learners_pass() -> None:
    learner = build_learner(bandit_setup(lam=0.5))
    batch = hand_batch(learner.module.head_ids(), rows=4)
    mab = MultiAgentBatch({mid: SampleBatch(cols) for mid, cols in batch.items()}, env_steps=4 * len(batch))
    with pytest.raises(ValueError, match="one local learner"):
        learner.update(batch=mab, num_total_minibatches=2, timesteps={})
