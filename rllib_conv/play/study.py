"""`Study`: the participants of one study, their balanced assignment to conditions, pairing and rooms.

The flow of one participant:

1. **Enrol** (`enrol`): after consenting, with the id the recruitment platform put in the
   URL (or a generated one). The id is the participant's key, the token their proof:
   enrolling again with the id and the token the first enrolment gave (the page keeps it)
   resumes the same session (same condition and room), after a reload or a restart. The id
   alone is refused (409): ids travel in URLs others see, and must not hand over a session.
   Refusals are counted for the admin page.
2. **Assignment**: to the condition with the fewest participants so far, ties broken at
   random (block randomisation: after every round of len(conditions) arrivals the counts
   are equal).
3. **Play**: an agent condition opens a room at once; in the human condition the
   participant waits until another waiting participant is connected (a live page:
   `connect`), and the two are paired, the earlier one in seat 1. A participant waits at
   most `pair_timeout` seconds; a room where nobody moves for `idle_timeout` seconds ends.
4. **Completion**: when the session is played to the end (or ends early) each participant
   gets a completion code (`--completion-code`, or a random one per participant), shown
   on their page and stored with them.

Everything is written to the database (`store.Store`) before memory changes and before
anyone is told; `Study(...)` on an existing database restores every open room by replay,
so participants resume with their id after the server was killed. Listeners registered
with `connect` are called after every change that concerns their participant (the server
pushes the new view through a WebSocket).
"""

from __future__ import annotations

import logging
import re
import secrets
import sqlite3
import threading
import time
from typing import Any, Callable

import numpy as np

from rllib_conv.play.agent import AdaptiveAgent, responder_prior
from rllib_conv.play.bandit_room import BanditRoom
from rllib_conv.play.blocks_room import BlocksRoom
from rllib_conv.play.conditions import Condition, StudySettings
from rllib_conv.play.room import CallLater, PlayError, Room, shown_value, thread_call_later
from rllib_conv.play.store import Participant, RoomRecord, Store

log = logging.getLogger(__name__)

PARTICIPANT_ID = re.compile(r"[A-Za-z0-9._-]{1,64}")  # whole (fullmatch): no trailing newline either
RECENT_REFUSALS = 20  # refused re-enrolments the admin page lists
CODE_ALPHABET = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"  # no 0/O, 1/I: codes are read and typed
CODE_LENGTH = 8
VERSIONS_PER_START = 10**9
END_REASONS = {
    "no_partner": "no other participant arrived in time to play with you",
    "idle": "nobody moved for a long time",
}

Listener = Callable[[], None]


class Study:
    """The participants, conditions and rooms of one study (module docstring).

    `call_later` schedules the agents' delayed blocks moves (the server's event loop, or
    threads); `clock` gives the time the timeouts are measured with.
    """

    def __init__(
        self,
        settings: StudySettings,
        store: Store,
        call_later: CallLater = thread_call_later,
        clock: Callable[[], float] = time.time,
    ) -> None:
        self.settings = settings
        self.store = store
        self.call_later = call_later
        self.clock = clock
        store.check_settings(settings.replay_settings(), {c.name: (c.kind, c.description) for c in settings.conditions})
        self.participants: dict[str, Participant] = {p.id: p for p in store.participants()}
        self._by_token = {p.token: p for p in self.participants.values()}
        self.rooms: dict[int, Room] = {}
        self._seated: dict[int, dict[int, str]] = {}  # pair -> seat -> participant id
        self._activity: dict[int, float] = {}  # pair -> time of its last change
        self._listeners: dict[str, list[Listener]] = {}
        self._present: dict[str, int] = {}  # participant id -> open live connections
        # Grows with every change, across restarts too: views carry it so a page drops stale ones.
        self.version = store.count_start() * VERSIONS_PER_START
        self._lock = threading.RLock()
        self._rng = np.random.default_rng([settings.seed, len(self.participants)])
        self.refused: list[dict[str, Any]] = []  # the latest refused re-enrolments (id, time), newest last
        self._restore()

    # -- restart ---------------------------------------------------------------------------
    def _restore(self) -> None:
        """Rebuild every open room from the database by replay (nothing is written but unfinished endings)."""
        for p in self.participants.values():
            if p.pair is not None:
                self._seated.setdefault(p.pair, {})[p.seat] = p.id
        for record in self.store.rooms(("playing",)):
            room = self._build(record)
            room.restore()
            self._activity[record.pair] = record.updated
            self._add(room)
        for room in list(self.rooms.values()):
            room.start()
            self._finish_if_done(room)

    # -- enrolment and assignment ------------------------------------------------------------
    def enrol(self, participant_id: Any = None, consent: Any = None, token: Any = None) -> Participant:
        """Enrol a participant who consented, or resume the one with this id when `token` is theirs; PlayError 400/409/503."""
        if consent is not True:
            raise PlayError(400, f"consent must be true (the participant agreed to the consent form), got {shown_value(consent)}")
        if participant_id is not None and not (isinstance(participant_id, str) and PARTICIPANT_ID.fullmatch(participant_id)):
            raise PlayError(
                400,
                f"participant must be an id of 1-64 letters, digits, '.', '-' or '_' (as recruitment platforms pass it), got {shown_value(participant_id)}",
            )
        with self._lock:
            if participant_id in self.participants:
                p = self.participants[participant_id]
                # surrogatepass: JSON may carry a lone surrogate ("\ud800"), which plain encode() refuses
                if not (
                    isinstance(token, str) and secrets.compare_digest(token.encode("utf-8", "surrogatepass"), p.token.encode())
                ):
                    self._refuse_resume(p)
                self._seat_with_agent(p)  # an earlier enrolment whose room could not be opened
                return p
            pid = participant_id or self._new_id()
            condition = self._assign()
            now = self.clock()
            p = Participant(id=pid, token=secrets.token_urlsafe(18), condition=condition.name, created=now, updated=now)
            try:
                self.store.add_participant(p)
            except sqlite3.Error as exc:
                raise PlayError(503, f"could not enrol you ({exc}); please reload the page") from None
            self.participants[pid] = p
            self._by_token[p.token] = p
            self.version += 1
            self._seat_with_agent(p)
            return p

    def _refuse_resume(self, p: Participant) -> None:
        """Refuse re-enrolling `p` without their token (PlayError 409), counted for the admin page."""
        try:
            self.store.count_refused_resume()
        except sqlite3.Error as exc:
            log.warning("could not count a refused re-enrolment of %s (%s)", p.id, exc)
        self.refused = [*self.refused, {"participant": p.id, "at": self.clock()}][-RECENT_REFUSALS:]
        log.warning("refused re-enrolling participant %s without their session token", p.id)
        raise PlayError(
            409,
            "This study link has already been used to start a session in another browser. Please continue in the browser "
            "where you started (the page picks up where you left off), or contact the researcher.",
        )

    def _seat_with_agent(self, p: Participant) -> None:
        """Open the room of a participant of an agent condition who has none yet."""
        condition = self.settings.condition(p.condition)
        if p.state == "waiting" and condition.agent is not None:
            person = self.settings.person_seat or 3 - condition.agent.ego_seat
            self._open(condition, {person: p.id})

    def _new_id(self) -> str:
        while True:
            pid = "anon-" + secrets.token_hex(6)
            if pid not in self.participants:
                return pid

    def _assign(self) -> Condition:
        """The condition with the fewest participants so far; ties broken at random."""
        counts = {c.name: 0 for c in self.settings.conditions}
        for p in self.participants.values():
            if p.condition in counts:
                counts[p.condition] += 1
        fewest = min(counts.values())
        names = [n for n, k in counts.items() if k == fewest]
        return self.settings.condition(names[int(self._rng.integers(len(names)))])

    # -- rooms -----------------------------------------------------------------------------
    def _open(self, condition: Condition, seats: dict[int, str]) -> Room:
        agent_seat = None if condition.agent is None else 3 - next(iter(seats))
        now = self.clock()
        try:
            pair = self.store.open_room(self.settings.game, condition.name, agent_seat, seats, now)
        except sqlite3.Error as exc:
            raise PlayError(503, f"could not start your session ({exc}); please reload the page") from None
        for seat, pid in seats.items():
            p = self.participants[pid]
            p.pair, p.seat, p.state, p.updated = pair, seat, "playing", now
        self._seated[pair] = dict(seats)
        self._activity[pair] = now
        self.version += 1
        room = self._build(RoomRecord(pair, self.settings.game, condition.name, agent_seat, "playing", None, now, now))
        self._add(room)
        room.start()
        return room

    def _build(self, record: RoomRecord) -> Room:
        """The room object of a stored room, with a fresh agent for an agent condition."""
        s = self.settings
        condition = s.condition(record.condition)
        agent = None
        if condition.agent is not None:
            a = condition.agent
            in_ego_seat = s.game == "bandit" or record.agent_seat == a.ego_seat
            if in_ego_seat:
                prior = a.priors["train" if s.game == "bandit" else "task"]  # the bandit room switches to "test" with the task
            else:
                prior = responder_prior  # no trained module for P2: the scripted responder (see agent.py)
            agent = AdaptiveAgent(prior, step_size=a.step_size, greedy=a.greedy, seed=[a.seed, record.pair])
            if a.conventions is not None and in_ego_seat:  # the heads and the plan are the trained seat's
                agent = a.conventions.agent(agent, prior, seed=[a.seed, record.pair, 1])
        if s.game == "bandit":
            return BanditRoom(
                record.pair,
                self.store,
                agent,
                record.agent_seat,
                condition.agent.priors if agent else None,
                tries=s.tries,
                call_later=self._call_later,
            )
        return BlocksRoom(
            record.pair,
            self.store,
            agent,
            record.agent_seat,
            s.new_task,
            s.games,
            s.seed,
            s.agent_delay,
            call_later=self._call_later,
        )

    def _call_later(self, delay: float, callback: Callable[[], None]) -> Any:
        """`call_later` for rooms: the callback takes the study's lock first, as requests do (one lock order, no deadlock)."""

        def locked() -> None:
            with self._lock:
                callback()

        return self.call_later(delay, locked)

    def _add(self, room: Room) -> None:
        room.on_change = self._changed
        self.rooms[room.pair] = room

    def _changed(self, room: Room) -> None:
        with self._lock:
            self._activity[room.pair] = self.clock()
            self.version += 1
            self._finish_if_done(room)
            self._notify(self._seated.get(room.pair, {}).values())

    def _finish_if_done(self, room: Room) -> None:
        """Give out completion codes once a room has played its whole session (retried if the write fails)."""
        if room.finished and any(self.participants[pid].state == "playing" for pid in self._seated[room.pair].values()):
            self._end(room.pair, "finished", None)

    def _end(self, pair: int | None, state: str, reason: str | None, pids: list[str] | None = None) -> None:
        """End room `pair` (or, with None, the participants `pids` who have none); if the write fails, a later call retries."""
        pids = list(self._seated[pair].values()) if pair is not None else pids or []
        codes = {
            pid: self.settings.completion_code or "".join(secrets.choice(CODE_ALPHABET) for _ in range(CODE_LENGTH))
            for pid in pids
        }
        now = self.clock()
        try:
            self.store.close_room(pair, state, reason, codes, now)
        except sqlite3.Error as exc:
            log.warning("could not end room %s (%s); will retry", pair, exc)
            return
        for pid, code in codes.items():
            p = self.participants[pid]
            p.state, p.end_reason, p.completion_code, p.updated = state, reason, code, now
        if pair is not None:
            self.rooms[pair].close()  # kept: its view (history, score) stays on the participants' pages
            self._activity.pop(pair, None)
        self.version += 1
        self._notify(pids)

    # -- live pages and pairing -----------------------------------------------------------------
    def connect(self, token: Any, listener: Listener) -> tuple[Participant, Callable[[], None]]:
        """Register a live page of the participant holding `token`; return them and the function that unregisters it.

        A waiting participant of the human condition is paired as soon as another one is
        connected too.
        """
        with self._lock:
            p = self.participant(token)
            self._listeners.setdefault(p.id, []).append(listener)
            self._present[p.id] = self._present.get(p.id, 0) + 1
            self._pair_waiting()

        def disconnect() -> None:
            with self._lock:
                self._listeners[p.id].remove(listener)
                self._present[p.id] -= 1

        return p, disconnect

    def _pair_waiting(self) -> None:
        waiting = [p for p in self.participants.values() if p.state == "waiting" and self._present.get(p.id, 0) > 0]
        waiting.sort(key=lambda p: p.created)
        by_condition: dict[str, list[Participant]] = {}
        for p in waiting:
            by_condition.setdefault(p.condition, []).append(p)
        for name, queue in by_condition.items():
            for first, second in zip(queue[::2], queue[1::2]):
                try:
                    self._open(self.settings.condition(name), {1: first.id, 2: second.id})
                except PlayError as err:
                    log.warning("could not pair %s and %s: %s", first.id, second.id, err.message)
                    return
                self._notify([first.id, second.id])

    def _notify(self, pids: Any) -> None:
        for pid in list(pids):
            for listener in list(self._listeners.get(pid, ())):
                listener()

    # -- requests --------------------------------------------------------------------------------
    def participant(self, token: Any) -> Participant:
        """The participant holding `token`; PlayError 403 if none does."""
        p = self._by_token.get(token) if isinstance(token, str) else None
        if p is None:
            raise PlayError(403, "unknown or missing participant token: open the study link again to resume your session")
        return p

    def move(self, token: Any, payload: dict[str, Any]) -> dict[str, Any]:
        """Play the move in `payload` for the participant holding `token`; return their new view."""
        with self._lock:
            p = self.participant(token)
            if p.state == "waiting":
                raise PlayError(409, "you have no partner yet: wait until another participant joins")
            if p.state != "playing":
                raise PlayError(409, "your session is over: there is nothing more to play")
            self.rooms[p.pair].move(p.seat, payload)
            return self.view(p)

    def view(self, p: Participant) -> dict[str, Any]:
        """What participant `p`'s page shows: their room's view for their seat, or where they stand."""
        with self._lock:
            room = self.rooms.get(p.pair) if p.pair is not None else None
            if room is not None:
                self._finish_if_done(room)  # a finished room whose codes could not be written yet
            out: dict[str, Any] = {"game": self.settings.game, "partner": "nobody", "played": 0}
            if room is not None:
                out = room.view(p.seat)
            out.update({"participant": p.id, "completion_code": p.completion_code, "version": self.version})
            if p.state == "waiting":
                left = max(0, round(self.settings.pair_timeout - (self.clock() - p.created)))
                out.update(
                    {
                        "phase": "waiting_for_partner",
                        "status": f"Waiting for another participant to join (at most {left} more seconds). Keep this page open.",
                    }
                )
            elif p.state == "ended":
                out.update(
                    {
                        "phase": "ended",
                        "status": f"This session has ended early: {END_REASONS.get(p.end_reason, p.end_reason)}. Thank you for your time.",
                    }
                )
            elif p.state == "finished":
                out["phase"] = "finished"
                if room is None:
                    out["status"] = "Session finished. Thank you!"
            return out

    # -- timeouts --------------------------------------------------------------------------------
    def sweep(self) -> None:
        """End what has waited too long: participants without a partner, rooms where nobody moved."""
        with self._lock:
            now = self.clock()
            late = [
                p.id for p in self.participants.values() if p.state == "waiting" and now - p.created > self.settings.pair_timeout
            ]
            if late:
                self._end(None, "ended", "no_partner", late)
            for pair, at in list(self._activity.items()):
                if now - at > self.settings.idle_timeout:
                    self._end(pair, "ended", "idle")

    # -- admin -----------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """The admin page's numbers: per condition its description and participants per state, rooms, tries."""
        with self._lock:
            counts = self.store.counts()
            conditions = []
            for name, (kind, description) in self.store.condition_descriptions().items():
                active = any(c.name == name for c in self.settings.conditions)
                conditions.append({"name": name, "kind": kind, "description": description, "active": active, **counts[name]})
            connected = sum(1 for n in self._present.values() if n > 0)
            return {
                "game": self.settings.game,
                "conditions": conditions,
                "connected": connected,
                "participants": len(self.participants),
                "refused_resumes": self.store.refused_resumes(),
                "recent_refused": [r["participant"] for r in self.refused],
            }

    def close(self) -> None:
        """Stop every room's agent timers (the server is stopping)."""
        with self._lock:
            for room in self.rooms.values():
                room.close()
