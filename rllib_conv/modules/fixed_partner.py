"""A fixed partner as an RLlib module: a scripted `Partner` that RLlib samples but never trains.

It has no framework, no parameters and no `ValueFunctionAPI`, so learners give it no
optimizer and PPO's value/advantage code skips it.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.rl_module import RLModule

import rllib_conv.partners  # noqa: F401  (registers every built-in partner kind in this process)
from rllib_conv.modules.task_module import split_obs
from rllib_conv.partners.kinds import partner_from_spec


def _numpy(x: Any) -> np.ndarray:
    return x.detach().cpu().numpy() if hasattr(x, "detach") else np.asarray(x)


class FixedPartnerModule(RLModule):
    """Wraps the partner described by `model_config["partner"]` (a manifest spec).

    `model_config["seed"]` seeds stochastic partners.
    """

    framework = None

    def setup(self) -> None:
        self.partner = partner_from_spec(self.model_config["partner"])
        self.partner.seed(self.model_config.get("seed"))

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        obs, mask = split_obs(batch)
        obs = _numpy(obs)
        mask = np.ones((len(obs), self.action_space.n), dtype=np.int8) if mask is None else _numpy(mask).astype(np.int8)
        return {Columns.ACTIONS: self.partner.act_batch(obs, mask)}

    def _forward_train(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        raise RuntimeError(f"fixed partner {self.partner.name!r} is never trained")

    def get_state(self, *args, **kwargs) -> dict:
        return {}

    def set_state(self, state: dict) -> None:
        pass
