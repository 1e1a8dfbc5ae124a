"""The partner module g^p_i: the ego's conventions with one partner, on top of the task module.

Policy logits = task logits + head logits; value = task value + head value. The head
holds an *unregistered* reference to the shared `TaskModule` (set by
`ConventionMultiRLModule`), so the task weights are not among the head's parameters:
they live in one place, get one optimizer and are saved once.

With `init_seed` its initial weights, and with `sample_seed` the actions it samples while
exploring, come from generators of its own: a head then explores exactly as it would alone,
whatever other heads (other replicas' ones) sample beside it in the same env runner.
"""

from __future__ import annotations

from typing import Any

import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule

from rllib_conv.modules.mlp import masked_logits, mlp, seeded_generator
from rllib_conv.modules.task_module import TaskModule, split_obs

TASK_LOGITS = "task_logits"
TASK_VALUE = "task_value"


class PartnerHeadModule(TorchRLModule, ValueFunctionAPI):
    """Ego head for one partner. `model_config`: `hidden`, `z_dim`, `use_task_logits` (default True), `init_seed`.

    `use_task_logits=False` is BaselineModular: the policy uses the head's logits only.
    """

    def setup(self) -> None:
        cfg = self.model_config
        hidden = int(cfg["hidden"])
        z_dim = int(cfg.get("z_dim") or hidden)
        num_actions = int(self.action_space.n)
        self.use_task_logits = bool(cfg.get("use_task_logits", True))
        g = seeded_generator(cfg.get("init_seed"))
        self.pi = mlp([z_dim, hidden, hidden, num_actions], out_gain=0.01, generator=g)
        self.vf = mlp([z_dim, hidden, hidden, 1], out_gain=1.0, generator=g)
        self.__dict__["_task"] = None  # bypasses nn.Module registration on purpose

    @property
    def task(self) -> TaskModule:
        """The shared task module; raises if the head was built outside a ConventionMultiRLModule."""
        if self.__dict__["_task"] is None:
            raise RuntimeError("PartnerHeadModule has no task module; build it inside a ConventionMultiRLModule")
        return self.__dict__["_task"]

    def set_shared(self, task: TaskModule) -> None:
        """Point this head at the shared task module (not registered as a child)."""
        self.__dict__["_task"] = task

    def logits(self, z: torch.Tensor, task_logits: torch.Tensor, action_mask: torch.Tensor | None) -> torch.Tensor:
        """Return the ego's masked policy logits for this partner given the task output."""
        return self.combine(self.pi(z), task_logits, action_mask)

    def combine(self, head: torch.Tensor, task_logits: torch.Tensor, action_mask: torch.Tensor | None) -> torch.Tensor:
        """Return the masked policy logits from this head's own output `head` (= `self.pi(z)`) and the task logits."""
        return masked_logits(task_logits + head if self.use_task_logits else head, action_mask)

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        obs, mask = split_obs(batch)
        z, task_logits = self.task.policy(obs, mask)
        return {Columns.ACTION_DIST_INPUTS: self.logits(z, task_logits, mask)}

    def _forward_train(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        obs, mask = split_obs(batch)
        z, task_logits = self.task.policy(obs, mask)
        # z and the task value let PPO's value loss skip recomputing the task module.
        return {
            Columns.ACTION_DIST_INPUTS: self.logits(z, task_logits, mask),
            Columns.EMBEDDINGS: {"z": z, TASK_VALUE: self.task.value(obs)},
            TASK_LOGITS: task_logits,
        }

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> torch.Tensor:
        if embeddings is not None:
            return embeddings[TASK_VALUE] + self.vf(embeddings["z"]).squeeze(-1)
        obs, mask = split_obs(batch)
        return self.task.value(obs) + self.vf(self.task.policy(obs, mask).z).squeeze(-1)
