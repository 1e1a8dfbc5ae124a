"""A game room: one pair's session, who sits where, and the errors a move can get.

A room holds two seats, each a person or the adapting agent (`mode` "agent": one of each;
"human": two people). The study (`study.Study`) seats participants and maps their tokens
to seats; a room sees only seats. Every move names the `step` it answers (how many tries,
or blocks moves, the session has played), so a move sent twice, or retried after a lost
answer, is refused with 409 instead of being played twice.

All checks happen before anything changes, and what a move changes is written to the
study database (`store.Store`) before the room's memory changes: a bad move raises
`PlayError` (HTTP status + a sentence for the page) and leaves room and database as they
were; a failed write raises PlayError 503 and nothing was played. After every change
the room calls `on_change(room)` (the study pushes the new views to the players).

The games' rooms are `bandit_room.BanditRoom` and `blocks_room.BlocksRoom`; `restore`
replays a room from the database after a restart. Views (`Room.view(seat)`) are plain
JSON-able dicts the page renders as they are; the sentence in `status` says whose turn it is.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any, Callable, Protocol

from rllib_conv.play.agent import DEFAULT_STEP_SIZE, AdaptiveAgent, Prior
from rllib_conv.play.store import Store

GAMES: tuple[str, ...] = ("bandit", "blocks")
SEATS: tuple[int, ...] = (1, 2)
STUDY_TASKS: tuple[str, ...] = ("train", "test")
# What participants read: the paper's "Train task / Test task" and "context" are researchers' words.
TASK_LABELS = {"train": "Part 1 of 2", "test": "Part 2 of 2"}
CONTEXT_NAMES: tuple[str, ...] = ("A", "B", "C")
TRIES = 5
DEFAULT_GAMES = 5
CELL_NAMES: tuple[str, ...] = ("top-left", "top-right", "bottom-left", "bottom-right")
MAX_STEP = 10_000


class PlayError(Exception):
    """A request the study refuses: `status` is the HTTP status, `message` the sentence shown in the page, `headers` extra answer headers."""

    def __init__(self, status: int, message: str, headers: dict[str, str] | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.message = message
        self.headers = headers


class Cancellable(Protocol):
    def cancel(self) -> None: ...


# (delay in seconds, callback) -> a handle whose cancel() stops it: loop.call_later in the
# server, `thread_call_later` elsewhere.
CallLater = Callable[[float, Callable[[], None]], Cancellable]


def thread_call_later(delay: float, callback: Callable[[], None]) -> Cancellable:
    """Run `callback` after `delay` seconds in a daemon thread (rooms used without an event loop)."""
    timer = threading.Timer(delay, callback)
    timer.daemon = True
    timer.start()
    return timer


def parse_int(value: Any, name: str, low: int, high: int) -> int:
    """`value` as an int in [low, high] (JSON ints, integral floats, or strings of ASCII digits), else PlayError 400.

    Never converts through float (an int past 1e308 overflows it) and reads only ASCII
    digits (`str.isdigit` also accepts '²', which `int` refuses).
    """
    number: int | None = None
    if isinstance(value, bool) or value is None:
        pass
    elif isinstance(value, int):
        number = value
    elif isinstance(value, float):
        if math.isfinite(value) and value.is_integer():
            number = int(value)
    elif isinstance(value, str):
        digits = value.strip()
        unsigned = digits[1:] if digits.startswith("-") else digits
        if 0 < len(unsigned) < 20 and unsigned.isascii() and unsigned.isdigit():
            number = int(digits)
    if number is not None and low <= number <= high:
        return number
    shown = shown_value(value)
    raise PlayError(400, f"{name} must be an integer from {low} to {high}, got {shown}")


def shown_value(value: Any) -> str:
    """`value` for an error message: its repr, cut to 40 characters (an int is cut before its repr, which may not be allowed)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**40:
        return "an integer of more than 40 digits"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


@dataclass
class AgentSettings:
    """What the study needs to build one adapting agent per room of an agent condition.

    `priors`: the task-module prior per task ("train", "test" for the bandit; "task" for
    blocks); `ego_seat`: the seat the trained ego plays; `description`: one line for the
    admin page (never shown to participants).
    """

    priors: dict[str, Prior]
    ego_seat: int = 1
    step_size: float = DEFAULT_STEP_SIZE
    greedy: bool = False
    seed: int = 0
    description: str = "agent"
    # `--adapter posterior`: a `convention_agent.ConventionSource`, whose agent wraps the adapting one (in the trained seat).
    conventions: Any = None


class Room:
    """One pair's session: seats, a version counter, the database it writes to (module docstring)."""

    game: str = ""

    def __init__(
        self,
        pair: int,
        store: Store,
        agent: AdaptiveAgent | None = None,
        agent_seat: int | None = None,
        call_later: CallLater = thread_call_later,
    ) -> None:
        self.pair = pair
        self.store = store
        self.agent = agent
        self.agent_seat = agent_seat
        self.kinds: dict[int, str] = {1: "person", 2: "person"}
        if agent is not None:
            if agent_seat not in SEATS:
                raise ValueError(f"agent_seat must be 1 or 2, got {agent_seat!r}")
            self.kinds[agent_seat] = "agent"
        self.mode = "agent" if agent is not None else "human"
        self.call_later = call_later
        self.version = 0
        self.lock = threading.RLock()
        self.closed = False
        self.on_change: Callable[[Room], None] | None = None

    def partner_kind(self, seat: int) -> str:
        """Who sits opposite `seat`: "agent" or "person"."""
        return self.kinds[3 - seat]

    def _partner_words(self, seat: int) -> str:
        return "the agent" if self.partner_kind(seat) == "agent" else "your partner"

    def _bump(self) -> None:
        """Count a change and tell the study (which pushes the new views)."""
        self.version += 1
        if self.on_change is not None:
            self.on_change(self)

    def _check_step(self, payload: dict[str, Any], current: int, what: str) -> None:
        """Refuse a move that does not answer the current step (a repeat, or one sent for a past try)."""
        step = parse_int(payload.get("step"), "step", 0, MAX_STEP)
        if step != current:
            raise PlayError(
                409,
                f"this move answers {what} {step + 1}, but the session is at {what} {current + 1}: it was already played or is out of date",
            )

    def close(self) -> None:
        """Stop the room: no more agent moves (the session ended or the server is stopping)."""
        with self.lock:
            self.closed = True

    # -- per game -------------------------------------------------------------------
    @property
    def finished(self) -> bool:
        """Whether the whole session has been played."""
        raise NotImplementedError

    def start(self) -> None:
        """Begin (or, after `restore`, resume) play: the agent makes its first move if it is its turn."""

    def view(self, seat: int) -> dict[str, Any]:
        """What the player in `seat` may see, as a JSON-able dict."""
        raise NotImplementedError

    def move(self, seat: int, payload: dict[str, Any]) -> dict[str, Any]:
        """Play the move in `payload` for the player in `seat`; return their new view."""
        raise NotImplementedError

    def restore(self) -> None:
        """Replay what the database holds for this room (after a restart), writing nothing."""
        raise NotImplementedError

    def _common_view(self, seat: int) -> dict[str, Any]:
        return {"game": self.game, "you": seat, "partner": self.partner_kind(seat), "version": self.version}
