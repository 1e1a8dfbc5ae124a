"""The task module g^t: rules of the game, shared by every partner head.

A 2-layer ReLU policy tower maps the observation to the latent `z` (its last hidden
layer); `task logits = Linear(z)`. A separate 2-layer value tower gives the task
value. On its own the task module is a policy too: the marginal best response over
partners, which is what the regulariser trains it to be.

With `oracle` set in `model_config` (`{"env": ..., "env_config": ...}`) the task
logits are replaced by the true marginals: 0 on optimal actions, the float minimum
elsewhere (the paper's "oracle" curve). With `init_seed` the initial weights come from a
generator of their own, so a module starts the same whichever other modules are built
beside it (replicas packed into one algorithm start as each would alone). With
`sample_seed` the actions it samples while exploring come from a generator of its own too
(self-play seats of several pairs in one algorithm, MEP: each explores as it would alone).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.core.rl_module.torch import TorchRLModule

from rllib_conv.envs.oracles import oracle_for
from rllib_conv.envs.rllib_adapter import RLLIB_MASK_KEY, RLLIB_OBS_KEY
from rllib_conv.modules.mlp import masked_logits, mlp, seeded_generator


class TaskOutput(NamedTuple):
    """What the task module gives its partner heads for a batch of observations."""

    z: torch.Tensor  # [B, z_dim] latent
    logits: torch.Tensor  # [B, A] task logits, illegal actions masked


def split_obs(batch: dict[str, Any]) -> tuple[torch.Tensor, torch.Tensor | None]:
    """Return (observation vectors, action mask or None) from an RLlib batch."""
    obs = batch[Columns.OBS]
    if isinstance(obs, dict):
        return obs[RLLIB_OBS_KEY], obs.get(RLLIB_MASK_KEY)
    return obs, None


class TaskModule(TorchRLModule, ValueFunctionAPI):
    """Shared task module: observation -> (z, task logits), and a task value.

    `model_config` keys: `hidden` (layer size), `z_dim` (latent size, default = hidden),
    `oracle`, `init_seed` and `sample_seed` (optional, see the module docstring).
    """

    def setup(self) -> None:
        cfg = self.model_config
        hidden = int(cfg["hidden"])
        self.z_dim = int(cfg.get("z_dim") or hidden)
        obs_space = self.observation_space[RLLIB_OBS_KEY] if hasattr(self.observation_space, "spaces") else self.observation_space
        obs_dim = int(np.prod(obs_space.shape))
        num_actions = int(self.action_space.n)
        g = seeded_generator(cfg.get("init_seed"))
        self.pi_tower = mlp([obs_dim, hidden, self.z_dim], final_relu=True, generator=g)
        self.pi_out = mlp([self.z_dim, num_actions], out_gain=0.01, generator=g)
        self.vf = mlp([obs_dim, hidden, hidden, 1], out_gain=1.0, generator=g)
        # Not an attribute torch would save: its state travels with the RNG state (`training.rng_state`).
        self.sampler = seeded_generator(cfg.get("sample_seed"))
        self._oracle = None
        if cfg.get("oracle"):
            self._oracle = oracle_for(cfg["oracle"]["env"], cfg["oracle"].get("env_config", {}))

    def policy(self, obs: torch.Tensor, action_mask: torch.Tensor | None) -> TaskOutput:
        """Return z and the masked task logits for `obs` ([B, obs_dim])."""
        z = self.pi_tower(obs)
        if self._oracle is not None:
            optimal = torch.as_tensor(self._oracle(obs.detach().cpu().numpy()), device=obs.device)
            logits = torch.clamp(torch.log(optimal), min=torch.finfo(obs.dtype).min)
        else:
            logits = self.pi_out(z)
        return TaskOutput(z, masked_logits(logits, action_mask))

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        """Return the task value, shape [B]."""
        return self.vf(obs).squeeze(-1)

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        obs, mask = split_obs(batch)
        return {Columns.ACTION_DIST_INPUTS: self.policy(obs, mask).logits}

    def _forward_exploration(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        out = self._forward(batch)
        if self.sampler is None:
            return out  # RLlib (or the batched runner) draws from torch's global RNG
        logits = out[Columns.ACTION_DIST_INPUTS]
        # As the packed ego draws (`StackedEgoMultiRLModule`): a categorical sample from this module's generator.
        actions = torch.multinomial(torch.softmax(logits, dim=-1), 1, generator=self.sampler).squeeze(-1)
        logp = (logits - logits.logsumexp(dim=-1, keepdim=True)).gather(-1, actions.unsqueeze(-1)).squeeze(-1)
        return {**out, Columns.ACTIONS: actions, Columns.ACTION_LOGP: logp}

    def compute_values(self, batch: dict[str, Any], embeddings: Any = None) -> torch.Tensor:
        return self.value(split_obs(batch)[0])
