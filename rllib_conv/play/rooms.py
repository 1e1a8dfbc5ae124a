"""Game rooms: who sits where, whose turn it is, what each player may see, and what gets recorded.

A room is one session of one pair: a person with the agent (`mode="agent"`) or two people
(`mode="human"`, the second joins with the room code). Players hold a secret token; every
request names the room and the token. All checks happen before anything changes, so a bad
request (unknown room, wrong token, a move out of turn, an invalid arm) raises `PlayError`
(HTTP status + a message for the page) and leaves the room and its recording untouched.

- `BanditRoom`: the paper's study. Train task then Test task (`envs.make("bandit",
  task="user_study"[, new_task=True])`), contexts A, B, C in turn, 5 tries each. In a try
  both players pick an arm without seeing the other's pick; when both have picked, both
  picks are revealed, the try is recorded (one user-study CSV row) and the next try
  starts. The agent picks its arm at the start of a try, before the person, from its
  policy alone, and learns from the person's arm after the reveal.
- `BlocksRoom`: the 2x2 block placing game (`envs.make("blocks")`), `games` games in a
  row; P1 (red) sees the goal, P2 (blue) does not until the game ends. Moves alternate
  P1, P2, ...; every move is shown to both as it happens (the agent moves after
  `agent_delay` seconds so a person can follow). A finished game is recorded (6 rows).
- `Lobby`: creates and finds rooms, builds one adapting agent per agent room.

Views (`Room.view(token)`) are plain JSON-able dicts the page renders as they are; the
sentence in `status` says whose turn it is.
"""

from __future__ import annotations

import copy
import math
import secrets
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from rllib_conv import envs
from rllib_conv.envs.bandit import USER_STUDY_ARMS
from rllib_conv.envs.blocks import ACTION_NAMES, NUM_CELLS, NUM_MOVES, REMOVE
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY
from rllib_conv.play.agent import (
    DEFAULT_STEP_SIZE,
    AdaptiveAgent,
    Prior,
    bandit_observation,
    bandit_targets,
    blocks_p1_targets,
    blocks_p2_targets,
    responder_prior,
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


def _parse_int(value: Any, name: str, low: int, high: int) -> int:
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


class BanditRoom(Room):
    """The user-study bandit: Train then Test task, contexts A-C, `tries` tries each (module docstring)."""

    game = "bandit"

    def __init__(
        self,
        code: str,
        pair: int,
        mode: str,
        recorder: SessionRecorder,
        agent: AdaptiveAgent | None = None,
        agent_seat: int | None = None,
        priors: dict[str, Prior] | None = None,
        tries: int = TRIES,
    ) -> None:
        super().__init__(code, pair, mode, recorder)
        if not 1 <= tries <= TRIES:
            raise ValueError(f"tries must be in 1..{TRIES} (the user-study format), got {tries}")
        self.prizes = {task: envs.make("bandit", task="user_study", new_task=task == "test").prizes for task in STUDY_TASKS}
        self.schedule = [(task, c, t) for task in STUDY_TASKS for c in range(len(CONTEXT_NAMES)) for t in range(1, tries + 1)]
        self.tries = tries
        self.step = 0
        self.picks: dict[int, int | None] = {1: None, 2: None}  # 0-based arms of the current try
        self.history: list[dict[str, Any]] = []
        self.score = 0.0
        self.agent = agent
        self.agent_seat = agent_seat
        self.priors = priors or {}
        if agent is not None:
            if agent_seat not in SEATS:
                raise ValueError(f"agent_seat must be 1 or 2, got {agent_seat!r}")
            self.kinds[agent_seat] = "agent"
            self._agent_pick()

    @property
    def finished(self) -> bool:
        """Whether every try of both tasks has been played."""
        return self.step >= len(self.schedule)

    def _agent_pick(self) -> None:
        # The agent commits to its arm before the person picks: it never sees the person's choice.
        task, context, _ = self.schedule[self.step]
        self.agent.prior = self.priors[task]
        obs = bandit_observation(context, len(CONTEXT_NAMES))
        self.picks[self.agent_seat] = self.agent.act(obs, np.ones(USER_STUDY_ARMS, dtype=np.int8))

    def move(self, token: Any, payload: dict[str, Any]) -> dict[str, Any]:
        seat = self.seat_of(token)
        with self.lock:
            if self.finished:
                raise PlayError(409, f"the session is over: all {len(self.schedule)} tries have been played")
            if not self.full():
                raise PlayError(409, f"your partner has not joined yet: give them the room code {self.code}")
            arm = _parse_int(payload.get("arm"), "arm", 1, USER_STUDY_ARMS) - 1
            if self.picks[seat] is not None:
                raise PlayError(409, f"you already picked arm {self.picks[seat] + 1} for this try; wait for your partner's pick")
            self.picks[seat] = arm
            if all(p is not None for p in self.picks.values()):
                try:
                    self._resolve()
                except (OSError, ValueError) as exc:
                    self.picks[seat] = None  # not recorded, so not played: the person picks again
                    raise PlayError(500, f"could not record this try ({exc}); your pick was not counted, please pick again") from None
            self._bump()
            return self.view(token)

    def _resolve(self) -> None:
        task, context, attempt = self.schedule[self.step]
        a1, a2 = self.picks[1], self.picks[2]
        prize = float(self.prizes[task][context, a1]) if a1 == a2 else 0.0
        row = {"pair": self.pair, "task": task, "context": CONTEXT_NAMES[context], "try": attempt, "action_1": a1 + 1, "action_2": a2 + 1}
        self.log.append([row])  # first: if recording fails, nothing below happens
        self.history.append({"task": task, "context": CONTEXT_NAMES[context], "try": attempt, "arms": {1: a1 + 1, 2: a2 + 1}, "prize": prize})
        self.score += prize
        if self.agent is not None:
            person = 3 - self.agent_seat
            self.agent.learn(bandit_targets(context, len(CONTEXT_NAMES), USER_STUDY_ARMS, self.picks[person]))
        self.step += 1
        self.picks = {1: None, 2: None}
        if self.agent is not None and not self.finished:
            self._agent_pick()

    def _status(self, seat: int) -> tuple[str, str]:
        """(phase, sentence) for `seat`: whose turn it is."""
        partner = "the agent" if self.partner_kind(seat) == "agent" else "your partner"
        if self.finished:
            return "finished", f"Session finished: {self.score:g} prize{'' if self.score == 1 else 's'} in {len(self.schedule)} tries. Thank you!"
        if not self.full():
            return "waiting_for_partner", f"Waiting for your partner to join: give them the room code {self.code}."
        if self.picks[seat] is None:
            task, context, attempt = self.schedule[self.step]
            if task == "test" and context == 0 and attempt == 1:
                # The prizes change under the players' feet: say so, as the study's interface moved to a new task.
                return "choose", "The Test task starts: the green arms have changed. Your turn: pick an arm."
            return "choose", "Your turn: pick an arm."
        return "waiting", f"You picked arm {self.picks[seat] + 1}. Waiting for {partner} to pick."

    def view(self, token: Any) -> dict[str, Any]:
        seat = self.seat_of(token)
        with self.lock:
            phase, status = self._status(seat)
            out = self._common_view(seat) | {
                "phase": phase,
                "status": status,
                "score": self.score,
                "played": self.step,
                "total": len(self.schedule),
                "tries": self.tries,
                "your_choice": None if self.picks[seat] is None else self.picks[seat] + 1,
                # Whether (never which arm) the partner has picked: the reveal waits for both.
                "partner_chose": self.picks[3 - seat] is not None and self.full(),
                "history": [self._mine(h, seat) for h in self.history],
            }
            out["last"] = out["history"][-1] if self.history else None
            if self.finished:
                out.update({"task": None, "task_label": None, "context": None, "try": None, "arms": []})
            else:
                task, context, attempt = self.schedule[self.step]
                prizes = self.prizes[task][context]
                out.update(
                    {
                        "task": task,
                        "task_label": TASK_LABELS[task],
                        "context": CONTEXT_NAMES[context],
                        "try": attempt,
                        "arms": [{"arm": a + 1, "prize": float(prizes[a])} for a in range(len(prizes))],
                    }
                )
            return out

    @staticmethod
    def _mine(h: dict[str, Any], seat: int) -> dict[str, Any]:
        return {"task": h["task"], "context": h["context"], "try": h["try"], "you": h["arms"][seat], "partner": h["arms"][3 - seat], "prize": h["prize"]}


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
            action = _parse_int(payload.get("action"), "action", 0, len(ACTION_NAMES) - 1)
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
            seat = _parse_int(seat, "seat", 1, 2) if seat is not None else 3 - self.agent.ego_seat
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

