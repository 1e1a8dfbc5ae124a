"""`MarginalPPOLearner`: PPO plus the paper's marginal regulariser, with freezing that freezes.

Per minibatch, over the states of every ego head's rows (PPO's bootstrap padding rows
are dropped by `DropBootstrapRows` before minibatching), the regulariser is

    D = mean_s sum_a | softmax(task logits)(a|s) - mean_i softmax(task + head_i logits)(a|s) |

over all ego heads i (one per training partner), with no gradient stopping. The loss
adds `lam * D`; `lam = 0` leaves PPO's loss untouched (D is still logged, computed
without gradients). Settings come from `config.learners(learner_config_dict=...)`, the
fields of `LearnerSettings` (whose defaults are the only ones):

- `lam` (float, default 0): the regulariser weight.
- `freeze` (list): module IDs, or the groups `"task"` and `"heads"`, whose weights must
  not change: their parameters get `requires_grad=False` and no optimizer.
- `adam_eps` (float, default 1e-5, the paper's code): Adam's epsilon.
- `z_lr_scale` (float, default 1): the task module's z layers (its policy tower) learn at
  `lr * z_lr_scale` through an optimizer of their own; 0 freezes them.
- `head_l2` (float, default 0; not in the paper): weight of the head penalty

      H = mean_{i,s} sum_a (h_i(a|s) - mean_b h_i(b|s))^2

  on every ego head's own output h_i (before the task logits are added; centred, since
  a constant shift leaves the policy unchanged; illegal actions count too, their outputs
  never reach the policy). Where the task module alone already
  plays the partners' common response (the rules), PPO leaves heads and task module
  free to split the logits any way; H makes the task module carry them, so a head
  holds only what differs between partners (the conventions), and a frozen head stays
  out of the way when the task module is re-trained on a new task. H is always logged.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any

import torch
from ray.rllib.algorithms.ppo.torch.ppo_torch_learner import PPOTorchLearner
from ray.rllib.core import ALL_MODULES
from ray.rllib.core.learner.learner import DEFAULT_OPTIMIZER

from rllib_conv.learners.drop_bootstrap_rows import DropBootstrapRows
from rllib_conv.learners.settings import LearnerSettings
from rllib_conv.modules.multi import ALL_HEAD_LOGITS, ALL_HEAD_OUTPUTS, TASK_ID
from rllib_conv.modules.partner_head import TASK_LOGITS, PartnerHeadModule

MARGINAL_REG_KEY = "marginal_reg"
HEAD_L2_KEY = "head_l2"


def marginal_distance(task_logits: torch.Tensor, head_logits: list[torch.Tensor]) -> torch.Tensor:
    """Return mean over rows of sum_a |softmax(task) - mean_i softmax(head_i)|; logits are [B, A]."""
    mean_policy = torch.stack([torch.softmax(h, dim=-1) for h in head_logits]).mean(dim=0)
    return (torch.softmax(task_logits, dim=-1) - mean_policy).abs().sum(dim=-1).mean()


def head_size(head_outputs: torch.Tensor) -> torch.Tensor:
    """Return mean over heads and rows of sum_a (h(a) - mean_b h(b))^2 for head outputs [H, B, A]."""
    centred = head_outputs - head_outputs.mean(dim=-1, keepdim=True)
    return centred.pow(2).sum(dim=-1).mean()


class MarginalPPOLearner(PPOTorchLearner):
    """PPO learner for `ConventionMultiRLModule`s: regulariser, real freezing, Adam eps."""

    def build(self) -> None:
        super().build()
        # After PPO's GAE piece: advantages need the bootstrap rows, the losses do not.
        if self._learner_connector is not None:
            self._learner_connector.append(DropBootstrapRows())

    @cached_property
    def settings(self) -> LearnerSettings:
        """The regulariser, head penalty, freezing and Adam settings from `learner_config_dict`."""
        cfg = dict(self.config.learner_config_dict)
        return LearnerSettings(**{**cfg, "freeze": tuple(cfg.get("freeze", ()))})

    @property
    def lam(self) -> float:
        """The regulariser weight."""
        return float(self.settings.lam)

    @property
    def head_l2(self) -> float:
        """The head penalty's weight."""
        return float(self.settings.head_l2)

    def frozen_module_ids(self) -> set[str]:
        """Module IDs whose weights must not change (expands the groups "task" and "heads")."""
        frozen: set[str] = set()
        for item in self.settings.freeze:
            if item == "task":
                frozen.add(TASK_ID)
            elif item == "heads":
                frozen.update(mid for mid, m in self.module._rl_modules.items() if isinstance(m, PartnerHeadModule))
            else:
                frozen.add(item)
        return frozen

    def configure_optimizers_for_module(self, module_id: str, config: Any = None) -> None:
        module = self.module[module_id]
        if module_id in self.frozen_module_ids():
            for p in module.parameters():
                p.requires_grad_(False)
            return
        scale = float(self.settings.z_lr_scale)
        z_params = list(module.pi_tower.parameters()) if module_id == TASK_ID and scale != 1.0 else []
        z_ids = {id(p) for p in z_params}
        groups = {DEFAULT_OPTIMIZER: ([p for p in self.get_parameters(module) if id(p) not in z_ids], config.lr)}
        if z_params and scale == 0.0:
            for p in z_params:
                p.requires_grad_(False)
        elif z_params:
            # Adam is invariant to the gradient's scale: a slower z needs a learning rate of its own.
            groups["z"] = (z_params, config.lr * scale)
        eps = float(self.settings.adam_eps)
        for name, (params, lr) in groups.items():
            if params:
                self.register_optimizer(
                    module_id=module_id,
                    optimizer_name=name,
                    # foreach: one fused kernel per step instead of a Python loop over tensors.
                    optimizer=torch.optim.Adam(params, eps=eps, foreach=True),
                    params=params,
                    lr_or_lr_schedule=lr,
                )

    def compute_losses(self, *, fwd_out: dict[str, Any], batch: dict[str, Any]) -> dict[str, Any]:
        shared = fwd_out.pop(TASK_ID, None)  # the task module has no batch and no loss of its own
        losses = super().compute_losses(fwd_out=fwd_out, batch=batch)
        if shared is None:
            return losses
        with torch.set_grad_enabled(self.lam > 0 and torch.is_grad_enabled()):
            reg = marginal_distance(shared[TASK_LOGITS], list(shared[ALL_HEAD_LOGITS]))
        with torch.set_grad_enabled(self.head_l2 > 0 and torch.is_grad_enabled()):
            size = head_size(shared[ALL_HEAD_OUTPUTS])
        self.metrics.log_value((ALL_MODULES, MARGINAL_REG_KEY), reg.detach(), reduce="mean")
        self.metrics.log_value((ALL_MODULES, HEAD_L2_KEY), size.detach(), reduce="mean")
        if self.lam > 0:
            losses[MARGINAL_REG_KEY] = self.lam * reg
        if self.head_l2 > 0:
            losses[HEAD_L2_KEY] = self.head_l2 * size
        return losses
