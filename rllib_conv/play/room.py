"""A game room: one pair's session, its seats and tokens, and the errors a request can get.

A room is one session of one pair: a person with the agent (`mode="agent"`) or two people
(`mode="human"`, the second joins with the room code). Players hold a secret token; every
request names the room and the token. All checks happen before anything changes, so a bad
request (unknown room, wrong token, a move out of turn, an invalid arm) raises `PlayError`
(HTTP status + a message for the page) and leaves the room and its recording untouched.

The games' rooms are `bandit_room.BanditRoom` and `blocks_room.BlocksRoom`; `lobby.Lobby`
creates and finds them. Views (`Room.view(token)`) are plain JSON-able dicts the page
renders as they are; the sentence in `status` says whose turn it is.
"""

from __future__ import annotations

import math
import secrets
import threading
import time
from dataclasses import dataclass
from typing import Any

from rllib_conv.play.agent import (
    DEFAULT_STEP_SIZE,
    Prior,
)
from rllib_conv.play.recording import SessionRecorder

GAMES: tuple[str, ...] = ("bandit", "blocks")
MODES: tuple[str, ...] = ("agent", "human")
SEATS: tuple[int, ...] = (1, 2)
STUDY_TASKS: tuple[str, ...] = ("train", "test")
TASK_LABELS = {"train": "Train task", "test": "Test task"}
CONTEXT_NAMES: tuple[str, ...] = ("A", "B", "C")
TRIES = 5
DEFAULT_GAMES = 5
CELL_NAMES: tuple[str, ...] = ("top-left", "top-right", "bottom-left", "bottom-right")
CODE_ALPHABET = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"  # no 0/O, 1/I: codes are read aloud and typed
CODE_LENGTH = 4


class PlayError(Exception):
    """A request the room refuses: `status` is the HTTP status, `message` the sentence shown in the page."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status
        self.message = message


def parse_int(value: Any, name: str, low: int, high: int) -> int:
    """`value` as an int in [low, high] (JSON ints, or strings of digits), else PlayError 400."""
    if isinstance(value, bool) or value is None:
        ok = False
    elif isinstance(value, int):
        ok = True
    elif isinstance(value, float):
        ok = math.isfinite(value) and value == int(value)
    elif isinstance(value, str):
        ok = value.strip().lstrip("-").isdigit()
    else:
        ok = False
    if ok:
        number = int(float(value)) if not isinstance(value, str) else int(value.strip())
        if low <= number <= high:
            return number
    raise PlayError(400, f"{name} must be an integer from {low} to {high}, got {value!r}")


@dataclass
class AgentSettings:
    """What the lobby needs to build one adapting agent per agent room.

    `priors`: the task-module prior per task ("train", "test" for the bandit; "task" for
    blocks); `ego_seat`: the seat the trained ego plays (the other is the person's by
    default); `description`: one line shown in the page.
    """

    priors: dict[str, Prior]
    ego_seat: int = 1
    step_size: float = DEFAULT_STEP_SIZE
    greedy: bool = False
    seed: int = 0
    description: str = "agent"


class Room:
    """One pair's session: seats, tokens, a version counter the page long-polls on."""

    game: str = ""

    def __init__(self, code: str, pair: int, mode: str, recorder: SessionRecorder) -> None:
        self.code = code
        self.pair = pair
        self.mode = mode
        self.log = recorder.log(self.game, mode)
        self.tokens: dict[str, int] = {}
        self.kinds: dict[int, str] = {}  # seat -> "person" | "agent"
        self.version = 0
        self.lock = threading.RLock()
        self._changed = threading.Condition(self.lock)
        self.closed = False

    # -- seats ----------------------------------------------------------------------
    def add_person(self, seat: int | None = None) -> tuple[str, int]:
        """Seat a person (in `seat`, or the first free one); return (token, seat). PlayError 409 if full."""
        with self.lock:
            free = [s for s in SEATS if s not in self.kinds]
            if not free:
                raise PlayError(409, f"room {self.code} is full: both players have joined")
            if seat is not None and seat not in free:
                raise PlayError(409, f"seat {seat} in room {self.code} is taken")
            seat = free[0] if seat is None else seat
            token = secrets.token_urlsafe(12)
            self.tokens[token] = seat
            self.kinds[seat] = "person"
            if self.full():
                self._on_full()
            self._bump()
            return token, seat

    def _on_full(self) -> None:
        """Called (under the lock) when the second player sits down."""

    def seat_of(self, token: Any) -> int:
        """The seat of the player holding `token`; PlayError 403 if it is not a player of this room."""
        seat = self.tokens.get(token) if isinstance(token, str) else None
        if seat is None:
            raise PlayError(403, f"you are not a player of room {self.code} (unknown or missing player token); start or join a room from the home page")
        return seat

    def full(self) -> bool:
        """Whether both seats are taken."""
        return all(s in self.kinds for s in SEATS)

    def partner_kind(self, seat: int) -> str:
        """Who sits opposite `seat`: "agent", "person" or "nobody" (not joined yet)."""
        return self.kinds.get(3 - seat, "nobody")

    # -- change notification (long polling) -----------------------------------------
    def _bump(self) -> None:
        self.version += 1
        self._changed.notify_all()

    def wait_for_change(self, since: int, timeout: float) -> None:
        """Block until the room's version is past `since`, the room closes, or `timeout` seconds pass."""
        deadline = time.monotonic() + timeout
        with self.lock:
            while self.version <= since and not self.closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    return
                self._changed.wait(left)

    def close(self) -> None:
        """Wake every waiting request (the server is stopping)."""
        with self.lock:
            self.closed = True
            self._changed.notify_all()

    # -- per game -------------------------------------------------------------------
    def view(self, token: Any) -> dict[str, Any]:
        """What the player holding `token` may see, as a JSON-able dict."""
        raise NotImplementedError

    def move(self, token: Any, payload: dict[str, Any]) -> dict[str, Any]:
        """Play the move in `payload` for the player holding `token`; return their new view."""
        raise NotImplementedError

    def _common_view(self, seat: int) -> dict[str, Any]:
        return {
            "game": self.game,
            "room": self.code,
            "mode": self.mode,
            "pair": self.pair,
            "you": seat,
            "partner": self.partner_kind(seat),
            "version": self.version,
        }
