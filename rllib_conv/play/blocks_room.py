"""`BlocksRoom`: the 2x2 block placing game as a room.

`games` games in a row (`envs.make("blocks")`); P1 (red) sees the goal, P2 (blue) does not
until the game ends. Moves alternate P1, P2, ...; every move is shown to both as it happens
(the agent moves after `agent_delay` seconds so a person can follow). A finished game is
recorded (6 rows).
"""

from __future__ import annotations

import copy
import threading
from typing import Any

import numpy as np

from rllib_conv import envs
from rllib_conv.envs.blocks import ACTION_NAMES, NUM_CELLS, NUM_MOVES, REMOVE
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY
from rllib_conv.play.agent import (
    AdaptiveAgent,
    blocks_p1_targets,
    blocks_p2_targets,
)
from rllib_conv.play.recording import SessionRecorder
from rllib_conv.play.room import (
    CELL_NAMES,
    DEFAULT_GAMES,
    SEATS,
    PlayError,
    Room,
    parse_int,
)


class BlocksRoom(Room):
    """Block placing, `games` games; P1 sees the goal, P2 sees it at the end (module docstring)."""

    game = "blocks"

    def __init__(
        self,
        code: str,
        pair: int,
        mode: str,
        recorder: SessionRecorder,
        agent: AdaptiveAgent | None = None,
        agent_seat: int | None = None,
        new_task: bool = False,
        games: int = DEFAULT_GAMES,
        seed: int = 0,
        agent_delay: float = 0.0,
    ) -> None:
        super().__init__(code, pair, mode, recorder)
        if games < 1:
            raise ValueError(f"games must be at least 1, got {games}")
        self.env = envs.make("blocks", new_task=new_task)
        self.new_task = new_task
        self.games = games
        self.seed = seed
        self.game_no = 0
        self.moves: list[tuple[int, int]] = []  # (player, action) of the current game
        self.results: list[dict[str, Any]] = []
        self.score = 0.0
        self.agent = agent
        self.agent_seat = agent_seat
        self.agent_delay = agent_delay
        self._timer: threading.Timer | None = None
        self.error: str | None = None
        if agent is not None:
            if agent_seat not in SEATS:
                raise ValueError(f"agent_seat must be 1 or 2, got {agent_seat!r}")
            self.kinds[agent_seat] = "agent"
        self._new_game()

    @property
    def finished(self) -> bool:
        """Whether all games have been played."""
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
            self._maybe_agent()

    def _maybe_agent(self) -> None:
        if self.agent is None or self.finished or self.turn != self.agent_seat or not self.full():
            return
        if self.agent_delay <= 0:
            self._agent_move(self.game_no, len(self.moves))
            return
        self._timer = threading.Timer(self.agent_delay, self._agent_move, args=(self.game_no, len(self.moves)))
        self._timer.daemon = True
        self._timer.start()

    def _agent_move(self, game_no: int, move_no: int) -> None:
        with self.lock:
            # A stale timer (the room moved on or closed) does nothing.
            if self.closed or self.finished or game_no != self.game_no or move_no != len(self.moves) or self.turn != self.agent_seat:
                return
            obs = self.env.observe(self.env.agent_selection)
            action = self.agent.act(obs[OBS_KEY], obs[MASK_KEY])
            try:
                self._apply_recorded(self.agent_seat, action)
                self.error = None
            except (OSError, ValueError) as exc:
                # Shown in both pages; the agent tries its move again after a pause.
                self.error = f"could not record the game ({exc}); retrying"
                timer = threading.Timer(max(self.agent_delay, 2.0), self._agent_move, args=(game_no, move_no))
                timer.daemon = True
                self._timer = timer
                timer.start()
            self._bump()

    def _apply_recorded(self, seat: int, action: int) -> None:
        """Play `action` for `seat` (and, without delay, the agent's replies); all or nothing.

        If recording a finished game fails, the room returns to the state before this move
        (env, moves) and the error propagates: the move was not played.
        """
        snapshot = copy.deepcopy(self.env), list(self.moves)
        try:
            self._apply(seat, action)
        except BaseException:
            self.env, self.moves = snapshot
            raise

    def _apply(self, seat: int, action: int) -> None:
        self.env.step(action)
        self.moves.append((seat, action))
        if len(self.moves) == NUM_MOVES:
            self._finish_game()
        else:
            self._maybe_agent()

    def _finish_game(self) -> None:
        red_goal, blue_goal = self.env.goal
        score = float(self.env.rewards["player_0"])
        task = "test" if self.new_task else "train"
        rows = [
            {"pair": self.pair, "task": task, "game": self.game_no, "move": i + 1, "player": p, "action": a, "red_goal": red_goal, "blue_goal": blue_goal, "score": int(score)}
            for i, (p, a) in enumerate(self.moves)
        ]
        self.log.append(rows)
        self.results.append({"game": self.game_no, "goal": self.env.goal_grid().tolist(), "grid": self.env.grid.tolist(), "score": score, "moves": self._move_log()})
        self.score += score
        if self.agent is not None:
            targets = blocks_p1_targets(self.moves) if self.agent_seat == 1 else blocks_p2_targets(self.moves, (red_goal, blue_goal))
            self.agent.learn(targets)
        self._new_game()

    def _move_log(self) -> list[dict[str, Any]]:
        out = []
        for i, (p, a) in enumerate(self.moves):
            colour = "red" if p == 1 else "blue"
            what = f"{colour} on {CELL_NAMES[a]}" if a < NUM_CELLS else ("removes " + colour if a == REMOVE else "passes")
            out.append({"move": i + 1, "player": p, "action": a, "text": f"P{p} {what}"})
        return out

    def move(self, token: Any, payload: dict[str, Any]) -> dict[str, Any]:
        seat = self.seat_of(token)
        with self.lock:
            if self.finished:
                raise PlayError(409, f"the session is over: all {self.games} games have been played")
            if not self.full():
                raise PlayError(409, f"your partner has not joined yet: give them the room code {self.code}")
            action = parse_int(payload.get("action"), "action", 0, len(ACTION_NAMES) - 1)
            if self.turn != seat:
                who = "the agent" if self.kinds.get(self.turn) == "agent" else "your partner"
                raise PlayError(409, f"not your turn: move {len(self.moves) + 1} is P{self.turn}'s ({who})")
            try:
                self._apply_recorded(seat, action)
            except (OSError, ValueError) as exc:
                raise PlayError(500, f"could not record this game ({exc}); your move was not counted, please play it again") from None
            self._bump()
            return self.view(token)

    def view(self, token: Any) -> dict[str, Any]:
        seat = self.seat_of(token)
        with self.lock:
            colour = "red" if seat == 1 else "blue"
            partner = "the agent" if self.partner_kind(seat) == "agent" else "your partner"
            if self.finished:
                phase, status = "finished", f"Session finished: {self.score:g} points in {self.games} game{'s' if self.games > 1 else ''}. Thank you!"
            elif not self.full():
                phase, status = "waiting_for_partner", f"Waiting for your partner to join: give them the room code {self.code}."
            elif self.turn == seat:
                phase, status = "your_turn", f"Your turn (P{seat}, {colour}): move {len(self.moves) + 1} of {NUM_MOVES}."
            else:
                phase, status = "their_turn", f"Waiting for {partner} (P{self.turn}): move {len(self.moves) + 1} of {NUM_MOVES}."
            out = self._common_view(seat) | {
                "phase": phase,
                "status": status,
                "colour": colour,
                "score": self.score,
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

    def _on_full(self) -> None:
        self._maybe_agent()  # the agent may be P1 and move first

    def close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        super().close()
