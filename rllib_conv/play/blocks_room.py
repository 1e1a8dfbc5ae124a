"""`BlocksRoom`: the 2x2 block placing game as a room.

`games` games in a row (`envs.make("blocks")`); P1 (red) sees the goal, P2 (blue) does not
until the game ends. Moves alternate P1, P2, ...; every move is written to the database
(with the game's goal and score when it ends the game) before it is shown to both (the
agent moves after `agent_delay` seconds so a person can follow). Each game's goal is drawn
from (seed, pair, game), so `restore` replays a room from its stored moves exactly.
"""

from __future__ import annotations

import copy
import sqlite3
import time
from typing import Any

import numpy as np

from rllib_conv import envs
from rllib_conv.envs.blocks import ACTION_NAMES, NUM_CELLS, NUM_MOVES, REMOVE
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY
from rllib_conv.play.agent import (
    AdaptiveAgent,
    blocks_p1_targets,
    blocks_p2_moves,
    blocks_p2_targets,
)
from rllib_conv.play.room import (
    CELL_NAMES,
    DEFAULT_GAMES,
    CallLater,
    Cancellable,
    PlayError,
    Room,
    parse_int,
    thread_call_later,
)
from rllib_conv.play.store import Store

RETRY_S = 2.0  # after a failed write the agent tries its move again this much later


class BlocksRoom(Room):
    """Block placing, `games` games; P1 sees the goal, P2 sees it at the end (module docstring)."""

    game = "blocks"

    def __init__(
        self,
        pair: int,
        store: Store,
        agent: AdaptiveAgent | None = None,
        agent_seat: int | None = None,
        new_task: bool = False,
        games: int = DEFAULT_GAMES,
        seed: int = 0,
        agent_delay: float = 0.0,
        call_later: CallLater = thread_call_later,
    ) -> None:
        super().__init__(pair, store, agent, agent_seat, call_later)
        if games < 1:
            raise ValueError(f"games must be at least 1, got {games}")
        self.env = envs.make("blocks", new_task=new_task)
        self.new_task = new_task
        self.games = games
        self.seed = seed
        self.game_no = 0
        self.step = 0  # moves played in the whole session
        self.moves: list[tuple[int, int]] = []  # (player, action) of the current game
        self.results: list[dict[str, Any]] = []
        self.score = 0.0
        self.agent_delay = agent_delay
        self._timer: Cancellable | None = None
        self.error: str | None = None
        self._new_game()

    @property
    def finished(self) -> bool:
        return self.game_no > self.games

    @property
    def turn(self) -> int:
        """The seat to move (1 = P1, red; 2 = P2, blue)."""
        return 1 if self.env.agent_selection == "player_0" else 2

    def _new_game(self) -> None:
        self.game_no += 1
        self.moves = []
        if not self.finished:
            # Seeded per pair and game: a session can be replayed; pairs get different goals.
            self.env.reset(seed=int(np.random.SeedSequence([self.seed, self.pair, self.game_no]).generate_state(1)[0]))

    def start(self) -> None:
        with self.lock:
            self._maybe_agent()

    def _maybe_agent(self) -> None:
        if self.agent is None or self.closed or self.finished or self.turn != self.agent_seat:
            return
        if self.agent_delay <= 0:
            self._agent_move(self.step)
        else:
            self._timer = self.call_later(self.agent_delay, lambda step=self.step: self._agent_move(step))

    def _agent_move(self, step: int) -> None:
        with self.lock:
            # A stale timer (the room moved on or closed) does nothing.
            if self.closed or self.finished or step != self.step or self.turn != self.agent_seat:
                return
            obs = self.env.observe(self.env.agent_selection)
            action = self.agent.act(obs[OBS_KEY], obs[MASK_KEY])
            try:
                self._play(self.agent_seat, action)
                self.error = None
            except sqlite3.Error as exc:
                # Shown in both pages; the agent tries its move again after a pause.
                self.error = f"could not record the agent's move ({exc}); retrying"
                self._timer = self.call_later(max(self.agent_delay, RETRY_S), lambda: self._agent_move(step))
            self._bump()

    def _play(self, seat: int, action: int) -> None:
        """Play `action` for `seat`, written to the database first: all or nothing (sqlite3.Error leaves the room as it was)."""
        snapshot = copy.deepcopy(self.env)
        self.env.step(action)
        result = None
        if len(self.moves) + 1 == NUM_MOVES:
            red_goal, blue_goal = self.env.goal
            result = (int(red_goal), int(blue_goal), int(self.env.rewards["player_0"]))
        try:
            self.store.add_move(self.pair, self.step, self.game_no, len(self.moves) + 1, seat, action, time.time(), result)
        except sqlite3.Error:
            self.env = snapshot
            raise
        self._record(seat, action)
        self._maybe_agent()

    def _record(self, seat: int, action: int) -> None:
        """The room's memory after a (written or replayed) move already stepped in the env."""
        self.moves.append((seat, action))
        self.step += 1
        if len(self.moves) == NUM_MOVES:
            self._finish_game()

    def _finish_game(self) -> None:
        score = float(self.env.rewards["player_0"])
        self.results.append(
            {
                "game": self.game_no,
                "goal": self.env.goal_grid().tolist(),
                "grid": self.env.grid.tolist(),
                "score": score,
                "moves": self._move_log(),
            }
        )
        self.score += score
        if self.agent is not None:
            targets = (
                blocks_p1_targets(self.moves) if self.agent_seat == 1 else blocks_p2_targets(self.moves, tuple(self.env.goal))
            )
            self.agent.learn(targets)
            if self.agent_seat == 1:
                self.agent.watch(blocks_p2_moves(self.moves))
        self._new_game()

    def restore(self) -> None:
        with self.lock:
            for row in self.store.moves(self.pair):
                if row["step"] != self.step or row["game"] != self.game_no:
                    raise ValueError(
                        f"room {self.pair}: the database holds move {row['step']} of game {row['game']}, expected move {self.step} of game {self.game_no}"
                    )
                self.env.step(row["action"])
                self._record(row["player"], row["action"])

    def _move_log(self) -> list[dict[str, Any]]:
        out = []
        for i, (p, a) in enumerate(self.moves):
            colour = "red" if p == 1 else "blue"
            what = f"{colour} on {CELL_NAMES[a]}" if a < NUM_CELLS else ("removes " + colour if a == REMOVE else "passes")
            out.append({"move": i + 1, "player": p, "action": a, "text": f"P{p} {what}"})
        return out

    def move(self, seat: int, payload: dict[str, Any]) -> dict[str, Any]:
        with self.lock:
            if self.finished:
                raise PlayError(409, f"the session is over: all {self.games} games have been played")
            action = parse_int(payload.get("action"), "action", 0, len(ACTION_NAMES) - 1)
            self._check_step(payload, self.step, "move")
            if self.turn != seat:
                raise PlayError(409, f"not your turn: move {len(self.moves) + 1} is P{self.turn}'s ({self._partner_words(seat)})")
            try:
                self._play(seat, action)
            except sqlite3.Error as exc:
                raise PlayError(503, f"could not record your move ({exc}); it was not counted, please play it again") from None
            self._bump()
            return self.view(seat)

    def view(self, seat: int) -> dict[str, Any]:
        with self.lock:
            colour = "red" if seat == 1 else "blue"
            if self.finished:
                phase, status = (
                    "finished",
                    f"Session finished: {self.score:g} points in {self.games} game{'s' if self.games > 1 else ''}. Thank you!",
                )
            elif self.turn == seat:
                phase, status = "your_turn", f"Your turn (P{seat}, {colour}): move {len(self.moves) + 1} of {NUM_MOVES}."
            else:
                phase, status = (
                    "their_turn",
                    f"Waiting for {self._partner_words(seat)} (P{self.turn}): move {len(self.moves) + 1} of {NUM_MOVES}.",
                )
            out = self._common_view(seat) | {
                "phase": phase,
                "status": status,
                "colour": colour,
                "score": self.score,
                "step": self.step,
                "games": self.games,
                "game_no": min(self.game_no, self.games),
                "played": len(self.results),
                "new_task": self.new_task,
                "results": self.results,
                "last": self.results[-1] if self.results else None,
                "error": self.error,
            }
            if self.finished:
                out.update({"goal": None, "grid": None, "move": None, "turn": None, "moves": []})
            else:
                # P2 never sees the goal of a game in progress (it is revealed in `last` once the game ends).
                out.update(
                    {
                        "goal": self.env.goal_grid().tolist() if seat == 1 else None,
                        "grid": self.env.grid.tolist(),
                        "move": len(self.moves) + 1,
                        "turn": self.turn,
                        "moves": self._move_log(),
                    }
                )
            return out

    def close(self) -> None:
        with self.lock:
            if self._timer is not None:
                self._timer.cancel()
            super().close()
