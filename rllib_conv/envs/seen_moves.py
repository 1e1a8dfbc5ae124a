"""The other seats' moves as one seat (the ego) sees them: its own last observation and move, then theirs.

An adapter on equal information learns of a new partner only from what the ego's seat
observes: its own observations and the partner's actions, never the partner's observation
(issue 45). `SeenMoves` keeps, at each move of another seat, the ego's observation before
its last move, that move (-1 if it has not moved yet this episode) and the other seat's
action. In a simultaneous-move game the ego's observation is the step's; in a turn-based
one the partner's situation follows from it and the ego's move by the game's rules.
`envs.rllib_adapter.PettingZooMultiAgentEnv.record_seen_moves` fills one during training rollouts.
"""

from __future__ import annotations

import numpy as np


class SeenMoves:
    """The moves of the seats other than `ego`, each with the ego's last observation and move before it."""

    def __init__(self, ego: str) -> None:
        self.ego = ego
        self._observation: np.ndarray | None = None
        self._action = -1
        self._rows: list[tuple[np.ndarray, int, int, str]] = []

    def start(self) -> None:
        """A new episode: the ego has neither observed nor moved in it."""
        self._observation, self._action = None, -1

    def saw(self, agent: str, observation: np.ndarray) -> None:
        """`agent` was handed `observation` (a seat's own observation vector); the ego's is remembered."""
        if agent == self.ego:
            self._observation = np.array(observation, dtype=np.float32)

    def moved(self, agent: str, action: int) -> None:
        """`agent` played `action`: the ego's move is remembered; another seat's is recorded beside the ego's view."""
        if agent == self.ego:
            self._action = int(action)
        elif self._observation is not None:  # a partner moving before the ego saw anything: nothing to key it by
            self._rows.append((self._observation, self._action, int(action), agent))

    def take(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """(ego observations [N, d], ego moves [N], partner moves [N]) recorded since the last call; None if none."""
        seated = self.take_seated()
        return None if seated is None else seated[:3]

    def take_seated(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """`take`, and last the seat [N] (agent names) that made each move: games of more than two seats."""
        rows, self._rows = self._rows, []
        if not rows:
            return None
        observations, ego_moves, moves, agents = zip(*rows)
        return (
            np.stack(observations),
            np.array(ego_moves, dtype=np.int64),
            np.array(moves, dtype=np.int64),
            np.array(agents, dtype=object),
        )
