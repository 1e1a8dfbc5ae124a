"""Partner functions for the mapping tests (imported by path, as a user's would be)."""

from __future__ import annotations

import numpy as np


def last_partner(episode: int, partners: list[str], rng: np.random.Generator) -> str:
    """Every episode with the last partner."""
    return partners[-1]


def alternate_first_two(episode: int, partners: list[str], rng: np.random.Generator) -> str:
    """Episodes alternate between the first two partners."""
    return partners[episode % 2]


def nobody(episode: int, partners: list[str], rng: np.random.Generator) -> str:
    """A wrong answer: no such partner."""
    return "nobody"


NOT_CALLABLE = 3
