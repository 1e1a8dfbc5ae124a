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
    they hold randomness, `seed`. Partners whose `act` is a function of its inputs set
    `deterministic = True`; stochastic ones that can say what they draw from override
    `action_probs` (the convention-posterior adapter needs it of every training partner).
    Partners that change during play (an adapting ego) use `start_episode` and `observe_other`.
    """

    kind: ClassVar[str] = ""
    deterministic: ClassVar[bool] = False
    # Partners that learn from the other seat's moves during an episode (`observe_other`) set it: their
    # `action_probs` then hold at the evidence so far, so a game's exact return cannot score a whole episode by them.
    learns_in_play: ClassVar[bool] = False
    # Partners whose `act_batch` rows are independent, given the partner's RNG, and that keep no state between moves
    # (`start_episode` and `observe_other` do nothing) set it: `episodes.play_batched` may then play many games at once.
    batchable: ClassVar[bool] = False

    def __init__(self, name: str) -> None:
        self.name = name

    @abstractmethod
    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        """Return the action for one observation vector and its int8 action mask."""

    def act_batch(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """Return one action per row of `observations` (a [B, obs_dim] array)."""
        return np.array([self.act(o, m) for o, m in zip(observations, action_masks)], dtype=np.int64)

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """Return [B, A]: the probability of each action per row of `observations`.

        Deterministic partners give the one-hot of `act_batch`; a stochastic partner must
        override it (ValueError naming the kind otherwise).
        """
        if not self.deterministic:
            raise ValueError(
                f"partner {self.name!r} (kind {self.kind!r}) does not say what its actions are drawn from: "
                "override Partner.action_probs, or set deterministic = True if act is a function of its inputs"
            )
        masks = np.asarray(action_masks)
        out = np.zeros(masks.shape, dtype=np.float64)
        out[np.arange(len(masks)), self.act_batch(observations, masks)] = 1.0
        return out

    def start_episode(self) -> None:
        """A new episode begins (`partners.episodes.episode_stream` calls it); partners that adapt during play reset their per-episode state."""

    def observe_other(self, observation: np.ndarray, action_mask: np.ndarray, action: int, agent: str | None = None) -> None:
        """The other seat `agent` chose `action` at its `observation` (with its `action_mask`); partners that adapt during play
        learn from it (`agent` tells the seats apart in games of more than two)."""

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


class SampledPartner(Partner):
    """A stochastic partner defined by its `action_probs`: `act` draws from them with the partner's own seeded RNG.

    Subclasses implement `action_probs` (and `params`); saying what they draw from lets a
    game's exact return and best-response bound score them without sampling.
    """

    batchable = True  # defined by its action_probs: rows drawn independently from the partner's RNG

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._rng = np.random.default_rng()

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        p = self.action_probs(np.asarray(observation)[None], np.asarray(action_mask)[None])[0]
        return int(self._rng.choice(len(p), p=p))

    def seed(self, seed: int | None) -> None:
        self._rng = np.random.default_rng(seed)
