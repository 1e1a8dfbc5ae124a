"""Convention keys: which situations of a game carry a convention of their own.

A game declares `key(observation) -> int` (`GameRecord.convention_key`) when its
coordination problems come in separate situations that a partner can tell apart from its
own observation, and a partner's choice in one says nothing about its choice in another.
The convention-posterior adapter (`rllib_conv.adaptation.convention_posterior`) then also
considers partners that recombine known conventions situation by situation. Games without
a key (Hanabi, whose observations rarely repeat) judge each move on its own there.
The bandit's and blocks' keys sit in their folders (`envs/bandit/keys.py`, `envs/blocks/keys.py`).
"""

from __future__ import annotations

from rllib_conv.envs.game import KeyFn
from rllib_conv.envs.registry import game

__all__ = ["KeyFn", "convention_key"]


def convention_key(env_name: str) -> KeyFn | None:
    """The convention key of `env_name`, or None if each move is its own situation."""
    return game(env_name).convention_key
