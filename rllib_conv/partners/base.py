"""The `Partner` interface: a fixed (non-learning) policy for one seat of a game."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar

import numpy as np


class Partner(ABC):
    """A fixed partner policy: (observation, action mask) -> action.

    The same object drives the scripted demo, evaluation, and (wrapped in
    `modules.FixedPartnerModule`) a non-trained RLlib module. Subclasses set `kind`
    (the name used in population manifests) and implement `act`, `params` and, if
    they hold randomness, `seed`.
    """

    kind: ClassVar[str] = ""

    def __init__(self, name: str) -> None:
        self.name = name

    @abstractmethod
    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        """Return the action for one observation vector and its int8 action mask."""

    def act_batch(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """Return one action per row of `observations` (a [B, obs_dim] array)."""
        return np.array([self.act(o, m) for o, m in zip(observations, action_masks)], dtype=np.int64)

    def seed(self, seed: int | None) -> None:
        """Seed the partner's own RNG; deterministic partners ignore it."""

    @abstractmethod
    def params(self) -> dict[str, Any]:
        """Return the JSON-serialisable constructor arguments (without `name`)."""

    def to_spec(self) -> dict[str, Any]:
        """Return the manifest entry `{"name", "kind", "params"}` that rebuilds this partner."""
        return {"name": self.name, "kind": self.kind, "params": self.params()}

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, {self.params()})"
