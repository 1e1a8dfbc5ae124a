"""Partner schedules: which training partner each episode is played with (the choice behind the agent -> module mapping).

- `RoundRobin` (the default, the paper's): partners in turn, episode by episode.
- `WeightedPartners`: each episode's partner drawn with the given weights, from a
  generator seeded from the replica's seed (so a replica draws as it would alone).
- `FixedTeam`: the same team every episode (one partner per partner seat, per replica):
  adapting to one new team in a game of more than two seats.
- `PartnerFunction`: a function of the user's, named by import path
  (`package.module:function` or `package.module.function`), called as
  `function(episode, partners, rng) -> partner name` with the episode's number (0, 1, ...),
  the replica's training partners in order and that replica's own `numpy` generator.

A schedule answers `index(replica, episode, partners)` once per episode and replica, in
episode order; its state (the generators') travels with checkpoints. In a game of more than
two seats it is asked once per partner seat, seats after the first with `seat=j`: round
robin then goes through every team of partners in turn, the weighted draw draws each seat
on its own, and a function chooses for one partner seat only.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

import numpy as np


class RoundRobin:
    """Partners in turn: episode n plays partner n mod (number of partners) (P).

    With several partner seats, seat j plays the j-th base-P digit of n: every team in turn, each once per P**seats episodes.
    """

    def index(self, replica: int, episode: int, partners: list[str], seat: int = 0) -> int:
        return (episode // len(partners) ** seat) % len(partners)

    def get_state(self) -> dict[str, Any]:
        return {}

    def set_state(self, state: dict[str, Any]) -> None:
        pass


class FixedTeam:
    """Every episode replica r seats `teams[r][j]` in partner seat j (names among the replica's partners)."""

    def __init__(self, teams: list[tuple[str, ...]]) -> None:
        self.teams = [tuple(t) for t in teams]

    def index(self, replica: int, episode: int, partners: list[str], seat: int = 0) -> int:
        return partners.index(self.teams[replica][seat])

    def get_state(self) -> dict[str, Any]:
        return {}

    def set_state(self, state: dict[str, Any]) -> None:
        pass


class _Seeded:
    """A schedule with one numpy generator per replica, seeded from the replica's seed."""

    def __init__(self, seeds: list[int]) -> None:
        self.seeds = [int(s) for s in seeds]
        self._rngs = [np.random.default_rng([s, 0x5EED]) for s in self.seeds]

    def rng(self, replica: int) -> np.random.Generator:
        return self._rngs[replica]

    def get_state(self) -> dict[str, Any]:
        return {"rngs": [r.bit_generator.state for r in self._rngs]}

    def set_state(self, state: dict[str, Any]) -> None:
        for rng, s in zip(self._rngs, state.get("rngs", [])):
            rng.bit_generator.state = s


class WeightedPartners(_Seeded):
    """Each episode's partner drawn with probability proportional to its weight (`weights`: partner name -> weight)."""

    def __init__(self, weights: dict[str, float], seeds: list[int]) -> None:
        super().__init__(seeds)
        if not weights or any(w < 0 for w in weights.values()) or sum(weights.values()) <= 0:
            raise ValueError(f"mapping weights must be non-negative with a positive sum; got {weights}")
        self.weights = dict(weights)

    def index(self, replica: int, episode: int, partners: list[str], seat: int = 0) -> int:
        p = np.array([self.weights.get(name, 0.0) for name in partners], dtype=float)
        if p.sum() <= 0:
            raise ValueError(f"mapping weights {self.weights} give no weight to any of the partners {partners}")
        return int(self.rng(replica).choice(len(partners), p=p / p.sum()))


def load_function(path: str) -> Callable[..., Any]:
    """The callable named by `path` (`package.module:function` or `package.module.function`); ValueError naming what is wrong."""
    module_name, sep, attr = path.partition(":") if ":" in path else path.rpartition(".")
    if not module_name or not attr:
        raise ValueError(f"mapping function {path!r}: expected 'package.module:function'")
    try:
        fn = getattr(importlib.import_module(module_name), attr)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"mapping function {path!r} cannot be loaded: {exc}") from None
    if not callable(fn):
        raise ValueError(f"mapping function {path!r} is not callable")
    return fn


class PartnerFunction(_Seeded):
    """The user's `function(episode, partners, rng) -> partner name`, loaded from its import path where it runs."""

    def __init__(self, path: str, seeds: list[int]) -> None:
        super().__init__(seeds)
        self.path = path
        self._fn: Callable[..., Any] | None = None

    def index(self, replica: int, episode: int, partners: list[str], seat: int = 0) -> int:
        if seat:
            raise ValueError(
                f"mapping function {self.path!r} chooses the partner of one partner seat; a game of more than two seats "
                "takes the round robin or weighted mapping"
            )
        if self._fn is None:
            self._fn = load_function(self.path)
        name = self._fn(episode, list(partners), self.rng(replica))
        if name not in partners:
            raise ValueError(
                f"mapping function {self.path!r} returned {name!r} for episode {episode}; expected one of {partners}"
            )
        return partners.index(name)

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_fn": None}  # pickled to env runners by path, imported there
