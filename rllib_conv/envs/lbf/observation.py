"""The layout of a Level-Based Foraging observation vector, as `lbforaging` writes it, and how to read it back.

Each seat's vector is `lbforaging`'s flat observation (`grid_observation=False`, levels shown):
`food` triples `(row, col, level)` of the food it sees, in reading order, then one triple
`(row, col, level)` per player, itself first and the other players it sees after, in seat
order. Unused slots read `(-1, -1, 0)`. Coordinates are in the seat's view window (the
clipped square of `sight` cells around it), so with full sight (`sight = size`) they are
the field's own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# lbforaging's action indices (its `Action` enum): the policy's action i is the package's Action(i).
NONE, NORTH, SOUTH, WEST, EAST, LOAD = range(6)
NUM_ACTIONS = 6
ACTION_NAMES: tuple[str, ...] = ("none", "north", "south", "west", "east", "load")


def observation_size(players: int, food: int) -> int:
    """The length of one seat's vector: a triple per food slot and per player."""
    return 3 * (food + players)


@dataclass(frozen=True)
class SeenState:
    """What one seat's observation shows: the food and players in view, in the vector's order."""

    food: np.ndarray  # [n, 3] int: (row, col, level) of each visible food, in reading order
    players: np.ndarray  # [m, 3] int: (row, col, level) of each visible player, the seat itself first

    @property
    def me(self) -> np.ndarray:
        """The seat's own (row, col, level)."""
        return self.players[0]


def read_observation(observation: np.ndarray, food: int, players: int) -> SeenState:
    """Split a seat's vector of an env with `food` food slots and `players` players into what it sees.

    ValueError when the vector's size is not theirs (a partner built for other settings than the env's).
    """
    vec = np.asarray(observation, dtype=np.float64).reshape(-1)
    if len(vec) != observation_size(players, food):
        raise ValueError(
            f"lbf: an observation of {len(vec)} numbers is not one of an env with food={food} and players={players} "
            f"({observation_size(players, food)} numbers): give the partner the env's food and players"
        )
    triples = np.rint(vec).astype(np.int64).reshape(-1, 3)
    foods, players = triples[:food], triples[food:]
    return SeenState(food=foods[foods[:, 2] > 0], players=players[players[:, 0] >= 0])
