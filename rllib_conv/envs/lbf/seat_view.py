"""Another seat's observation and legal moves as the ego's observation shows them (`envs.seat_views`), full sight only.

With full sight (`sight = size`) every seat's vector holds the same food triples in the same
(reading) order and every player's triple, its own first and the others in seat order
(`observation.py`), in the field's own coordinates. So a partner's vector is the ego's with
the player triples put back in seat order and the partner's moved first, and its legal moves
follow from the food around it by `lbforaging`'s rules: none always; a step unless it leaves
the field or enters food (players do not block it); load next to food (not diagonally). With
partial sight the ego's vector shows neither what the partner sees nor where, so there is no
view (the factory answers None).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv.envs.lbf.env import LBFEnv
from rllib_conv.envs.lbf.observation import EAST, LOAD, NONE, NORTH, NUM_ACTIONS, SOUTH, WEST


class LBFSeatView:
    """Seat `seat`'s (observation, mask) from the ego's (seat `ego`) observation, in a field of `size` with full sight."""

    def __init__(self, players: int, food: int, size: int, ego: int, seat: int) -> None:
        if ego == seat or not (0 <= ego < players and 0 <= seat < players):
            raise ValueError(f"lbf: a seat view needs two different seats of {players}, got ego {ego} and seat {seat}")
        self.players, self.food, self.size, self.ego, self.seat = players, food, size, ego, seat

    def __call__(self, observation: np.ndarray, ego_move: int = -1) -> tuple[np.ndarray, np.ndarray]:
        triples = np.asarray(observation, dtype=np.float32).reshape(-1, 3)
        foods, seen = triples[: self.food], list(triples[self.food :])
        in_seats = seen[1 : self.ego + 1] + [seen[0]] + seen[self.ego + 1 :]  # the ego's own triple back in its seat
        order = [self.seat, *(i for i in range(self.players) if i != self.seat)]
        vector = np.concatenate([foods.reshape(-1), *(in_seats[i] for i in order)]).astype(np.float32)
        return vector, self._mask(foods, in_seats[self.seat])

    def _mask(self, foods: np.ndarray, me: np.ndarray) -> np.ndarray:
        field = np.zeros((self.size + 2, self.size + 2), dtype=bool)  # a border of one cell: no move leaves the field
        for row, col, level in np.rint(foods).astype(np.int64):
            if level > 0:
                field[row + 1, col + 1] = True
        border = np.ones_like(field)
        border[1:-1, 1:-1] = False
        row, col = (int(v) + 1 for v in np.rint(me[:2]))
        mask = np.zeros(NUM_ACTIONS, dtype=np.int8)
        mask[NONE] = 1
        for action, (r, c) in ((NORTH, (row - 1, col)), (SOUTH, (row + 1, col)), (WEST, (row, col - 1)), (EAST, (row, col + 1))):
            mask[action] = not (field[r, c] or border[r, c])
            mask[LOAD] |= field[r, c]
        return mask


def lbf_seat_view(env_config: dict[str, Any], ego_agent: str, agent: str) -> LBFSeatView | None:
    """The `GameRecord.seat_view` of Level-Based Foraging: seat `agent` as `ego_agent` sees it; None with partial sight."""
    env = LBFEnv(**env_config)  # its settings resolved and checked as the game's own
    if env.sight < env.size:
        return None
    seats = env.possible_agents
    return LBFSeatView(env.num_players, env.food, env.size, seats.index(ego_agent), seats.index(agent))
