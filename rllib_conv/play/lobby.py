"""`Lobby`: all rooms of one server; creates agent and two-person rooms, finds them by code, builds one adapting agent per agent room."""

from __future__ import annotations

import threading
import time
from typing import Any

import numpy as np

from rllib_conv.play.agent import (
    AdaptiveAgent,
    responder_prior,
)
from rllib_conv.play.bandit_room import BanditRoom
from rllib_conv.play.blocks_room import BlocksRoom
from rllib_conv.play.recording import SessionRecorder
from rllib_conv.play.room import (
    CODE_ALPHABET,
    CODE_LENGTH,
    DEFAULT_GAMES,
    GAMES,
    MODES,
    TRIES,
    AgentSettings,
    PlayError,
    Room,
    parse_int,
)


class Lobby:
    """All rooms of one server: creates agent and two-person rooms, finds them by code.

    `agent` is None when no trained ego was given (two-person rooms only).
    """

    def __init__(
        self,
        game: str,
        recorder: SessionRecorder,
        agent: AgentSettings | None = None,
        *,
        new_task: bool = False,
        games: int = DEFAULT_GAMES,
        tries: int = TRIES,
        seed: int = 0,
        agent_delay: float = 0.6,
        run_info: dict[str, Any] | None = None,
    ) -> None:
        if game not in GAMES:
            raise ValueError(f"game must be one of {list(GAMES)}, got {game!r}")
        self.game = game
        self.recorder = recorder
        self.agent = agent
        self.new_task = new_task
        self.games = games
        self.tries = tries
        self.seed = seed
        self.agent_delay = agent_delay
        self.run_info = run_info or {}
        self.rooms: dict[str, Room] = {}
        self._lock = threading.Lock()
        self._rng = np.random.default_rng()

    def info(self) -> dict[str, Any]:
        """What the home page needs: the game, whether an agent is available and its seats."""
        seats = ["Player 1", "Player 2"] if self.game == "bandit" else ["P1 (red, sees the goal)", "P2 (blue, goal hidden)"]
        return {
            "game": self.game,
            "agent": self.agent is not None,
            "agent_description": self.agent.description if self.agent else None,
            "ego_seat": self.agent.ego_seat if self.agent else None,
            "seats": seats,
            "tries": self.tries,
            "games": self.games,
            "new_task": self.new_task,
        }

    def _code(self) -> str:
        for _ in range(1000):
            code = "".join(self._rng.choice(list(CODE_ALPHABET), CODE_LENGTH))
            if code not in self.rooms:
                return code
        raise PlayError(503, "no free room code left; restart the server")

    def create(self, mode: Any, seat: Any = None) -> tuple[Room, str, int]:
        """Open a room: `mode` "agent" (the person sits in `seat`, 1 or 2) or "human" (creator is Player 1).

        Returns (room, the creator's token, their seat). PlayError 400 for a bad mode or
        seat, 409 for an agent room on a server started without a trained ego.
        """
        if mode not in MODES:
            raise PlayError(400, f"mode must be 'agent' (play with the agent) or 'human' (play with another person), got {mode!r}")
        if mode == "agent":
            if self.agent is None:
                raise PlayError(409, "this server has no trained agent: start it with `rllib-conv play RUN` to play with the agent")
            seat = parse_int(seat, "seat", 1, 2) if seat is not None else 3 - self.agent.ego_seat
            if self.game == "blocks" and seat == 2 and self.agent.ego_seat == 2:
                raise PlayError(409, "this agent was trained as P2 and there is no P1 agent: choose P1")
        else:
            seat = 1
        with self._lock:
            code = self._code()
            agent_seat = 3 - seat if mode == "agent" else None
            pair = self.recorder.new_session(
                {
                    "game": self.game,
                    "mode": mode,
                    "room": code,
                    "agent_seat": agent_seat,
                    "run": self.run_info if mode == "agent" else None,
                    "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
                }
            )
            room = self._build(code, pair, mode, agent_seat)
            self.rooms[code] = room
        token, seat = room.add_person(seat)
        return room, token, seat

    def _build(self, code: str, pair: int, mode: str, agent_seat: int | None) -> Room:
        agent = None
        if agent_seat is not None:
            s = self.agent
            if self.game == "bandit":
                prior = s.priors["train"]  # BanditRoom switches to "test" with the task
            elif agent_seat == s.ego_seat:
                prior = s.priors["task"]
            else:
                prior = responder_prior  # no trained module for P2: the scripted responder (see agent.py)
            agent = AdaptiveAgent(prior, step_size=s.step_size, greedy=s.greedy, seed=[s.seed, pair])
        if self.game == "bandit":
            return BanditRoom(code, pair, mode, self.recorder, agent, agent_seat, self.agent.priors if agent else None, tries=self.tries)
        return BlocksRoom(code, pair, mode, self.recorder, agent, agent_seat, self.new_task, self.games, self.seed, self.agent_delay)

    def room(self, code: Any) -> Room:
        """The room with `code` (case and spaces ignored); PlayError 404 naming the code if none."""
        key = code.strip().upper() if isinstance(code, str) else ""
        room = self.rooms.get(key)
        if room is None:
            raise PlayError(404, f"no room with code {code!r}: check the code your partner gave you")
        return room

    def join(self, code: Any) -> tuple[Room, str, int]:
        """Take the free seat of two-person room `code`; return (room, token, seat)."""
        room = self.room(code)
        if room.mode != "human":
            raise PlayError(409, f"room {room.code} is a game with the agent; only two-person rooms can be joined")
        token, seat = room.add_person()
        return room, token, seat

    def close(self) -> None:
        """Wake every waiting request and stop agent timers."""
        for room in list(self.rooms.values()):
            room.close()
