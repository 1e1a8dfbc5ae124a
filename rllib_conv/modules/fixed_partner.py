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
from rllib_conv.common.arrays import to_numpy
from rllib_conv.modules.task_module import split_obs
from rllib_conv.partners.kinds import partner_from_spec


class FixedPartnerModule(RLModule):
    """Wraps the partner described by `model_config["partner"]` (a manifest spec).

    `model_config["seed"]` seeds stochastic partners. After `record_moves()` it keeps every
    (observation, mask, action) it plays until `take_moves()` hands them over: what an
    adapter learns about a new partner from the env steps it has played.
    """

    framework = None

    def setup(self) -> None:
        self.partner = partner_from_spec(self.model_config["partner"])
        self.partner.seed(self.model_config.get("seed"))
        self._moves: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None

    def record_moves(self) -> None:
        """Keep the moves played from now on (until `take_moves`)."""
        self._moves = []

    def take_moves(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The (observations [N, d], masks [N, A], actions [N]) recorded since the last call; None if not recording."""
        if self._moves is None:
            return None
        moves, self._moves = self._moves, []
        if not moves:
            return None
        obs, masks, actions = zip(*moves)
        return np.concatenate(obs), np.concatenate(masks), np.concatenate(actions)

    def _forward(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        obs, mask = split_obs(batch)
        obs = to_numpy(obs)
        mask = np.ones((len(obs), self.action_space.n), dtype=np.int8) if mask is None else to_numpy(mask).astype(np.int8)
        actions = self.partner.act_batch(obs, mask)
        if self._moves is not None and len(obs):
            self._moves.append((np.array(obs), np.array(mask), np.asarray(actions)))
        return {Columns.ACTIONS: actions}

    def _forward_train(self, batch: dict[str, Any], **kwargs) -> dict[str, Any]:
        raise RuntimeError(f"fixed partner {self.partner.name!r} is never trained")

    def get_state(self, *args, **kwargs) -> dict:
        return {}

    def set_state(self, state: dict) -> None:
        pass
