"""The study database: every participant, room, pick, try and blocks move of one study, in SQLite.

One file per study (default `<study folder>/study.sqlite3`), written by one server process:

- **Durable before acknowledged.** WAL mode with `synchronous=FULL`: every write is one
  transaction, committed and fsynced before the method returns, so a response sent after a
  write never tells a participant something the file lacks; a SIGKILL (or a power cut)
  loses nothing that was acknowledged. A failed write rolls back whole and raises
  `sqlite3.Error`; the caller then changes nothing in memory either.
- **Schema versioned** with `PRAGMA user_version`: a new file gets `SCHEMA_VERSION`, an
  older one is migrated in order (`MIGRATIONS`), a newer one (written by a later release)
  is refused with a ValueError, read from the file's header before SQLite opens it: a
  refused file is left byte for byte as it was (no switch to WAL, no `-wal`/`-shm` files).
- **One study per file.** `check_settings` stores what a replay depends on (game, seed,
  tries, games, task) and each condition's description on first use and refuses a
  restart with different ones, naming the setting: restored sessions must replay exactly.

Tables (`pair` is a room's number, the `pair` column of the user-study CSV):

    settings      key, value
    conditions    name, kind ("agent" | "human"), description (admin only)
    participants  id (from the recruitment URL or generated), token, condition, pair, seat,
                  state (waiting | playing | finished | ended), end_reason, completion_code, times
    rooms         pair, game, condition, agent_seat (NULL: two people), state, end_reason, times
    picks         a person's pick in a try the partner has not answered yet (pair, step, seat, action)
    tries         one finished bandit try: pair, step, task, context, try, action_1, action_2, prize
    moves         one blocks move: pair, step, game, move, player, action
    games         one finished blocks game: pair, game, red_goal, blue_goal, score
"""

from __future__ import annotations

import sqlite3
import threading
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator, Mapping

DB_FILE = "study.sqlite3"
SQLITE_MAGIC = b"SQLite format 3\x00"
USER_VERSION_AT = 60  # the header's 4-byte big-endian `PRAGMA user_version` (sqlite.org/fileformat.html)
PARTICIPANT_STATES: tuple[str, ...] = ("waiting", "playing", "finished", "ended")
ROOM_STATES: tuple[str, ...] = ("playing", "finished", "ended")
OPEN_STATES: tuple[str, ...] = ("waiting", "playing")

SCHEMA_V1 = """
CREATE TABLE settings (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE conditions (
    name TEXT PRIMARY KEY,
    kind TEXT NOT NULL CHECK (kind IN ('agent', 'human')),
    description TEXT NOT NULL
);
CREATE TABLE rooms (
    pair INTEGER PRIMARY KEY,
    game TEXT NOT NULL,
    condition TEXT NOT NULL REFERENCES conditions(name),
    agent_seat INTEGER CHECK (agent_seat IN (1, 2)),
    state TEXT NOT NULL CHECK (state IN ('playing', 'finished', 'ended')),
    end_reason TEXT,
    created REAL NOT NULL,
    updated REAL NOT NULL
);
CREATE TABLE participants (
    id TEXT PRIMARY KEY,
    token TEXT NOT NULL UNIQUE,
    condition TEXT NOT NULL REFERENCES conditions(name),
    pair INTEGER REFERENCES rooms(pair),
    seat INTEGER CHECK (seat IN (1, 2)),
    state TEXT NOT NULL CHECK (state IN ('waiting', 'playing', 'finished', 'ended')),
    end_reason TEXT,
    completion_code TEXT,
    created REAL NOT NULL,
    updated REAL NOT NULL,
    UNIQUE (pair, seat)
);
CREATE TABLE picks (
    pair INTEGER NOT NULL REFERENCES rooms(pair),
    step INTEGER NOT NULL,
    seat INTEGER NOT NULL CHECK (seat IN (1, 2)),
    action INTEGER NOT NULL,
    at REAL NOT NULL,
    PRIMARY KEY (pair, step, seat)
);
CREATE TABLE tries (
    pair INTEGER NOT NULL REFERENCES rooms(pair),
    step INTEGER NOT NULL,
    task TEXT NOT NULL CHECK (task IN ('train', 'test')),
    context TEXT NOT NULL CHECK (context IN ('A', 'B', 'C')),
    try INTEGER NOT NULL CHECK (try BETWEEN 1 AND 5),
    action_1 INTEGER NOT NULL CHECK (action_1 BETWEEN 1 AND 4),
    action_2 INTEGER NOT NULL CHECK (action_2 BETWEEN 1 AND 4),
    prize REAL NOT NULL,
    at REAL NOT NULL,
    PRIMARY KEY (pair, step),
    UNIQUE (pair, task, context, try)
);
CREATE TABLE moves (
    pair INTEGER NOT NULL REFERENCES rooms(pair),
    step INTEGER NOT NULL,
    game INTEGER NOT NULL,
    move INTEGER NOT NULL CHECK (move BETWEEN 1 AND 6),
    player INTEGER NOT NULL CHECK (player IN (1, 2)),
    action INTEGER NOT NULL CHECK (action BETWEEN 0 AND 5),
    at REAL NOT NULL,
    PRIMARY KEY (pair, step),
    UNIQUE (pair, game, move)
);
CREATE TABLE games (
    pair INTEGER NOT NULL REFERENCES rooms(pair),
    game INTEGER NOT NULL,
    red_goal INTEGER NOT NULL,
    blue_goal INTEGER NOT NULL,
    score INTEGER NOT NULL,
    PRIMARY KEY (pair, game)
);
CREATE INDEX participants_open ON participants (state, condition);
"""

# MIGRATIONS[v] brings a file from version v to v + 1; version 0 is an empty file.
MIGRATIONS: dict[int, str] = {0: SCHEMA_V1}
SCHEMA_VERSION = max(MIGRATIONS) + 1


@dataclass
class Participant:
    """One participant as stored: who, which condition, where they sit and how their session stands."""

    id: str
    token: str
    condition: str
    state: str = "waiting"
    pair: int | None = None
    seat: int | None = None
    end_reason: str | None = None
    completion_code: str | None = None
    created: float = 0.0
    updated: float = 0.0


@dataclass
class RoomRecord:
    """One room as stored (the game state itself is in picks, tries, moves and games)."""

    pair: int
    game: str
    condition: str
    agent_seat: int | None
    state: str
    end_reason: str | None
    created: float
    updated: float


def db_path(path: str | Path) -> Path:
    """The database file of `path`: the file itself, or `DB_FILE` inside a study folder."""
    path = Path(path)
    return path / DB_FILE if path.is_dir() else path


def header_version(path: Path) -> int | None:
    """The schema version in the header of SQLite file `path`, read as plain bytes (None: no file, or an empty one).

    ValueError when the file is not an SQLite database. Opening the file with SQLite first
    would already change it (a journal mode, a `-shm` beside it).
    """
    try:
        with path.open("rb") as f:
            head = f.read(100)
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise ValueError(f"{str(path)!r} cannot be read ({exc.strerror or exc})") from None
    if not head:
        return None
    if len(head) < 100 or not head.startswith(SQLITE_MAGIC):
        raise ValueError(f"{str(path)!r} is not a study database (not an SQLite file)")
    return int.from_bytes(head[USER_VERSION_AT : USER_VERSION_AT + 4], "big")


def newer_schema_error(path: Path, version: int) -> ValueError:
    """The refusal of a database written by a later release."""
    return ValueError(
        f"{str(path)!r} has schema version {version}, newer than this release's {SCHEMA_VERSION}; use a newer rllib-conv"
    )


class Store:
    """The study database (module docstring); thread-safe, one writer at a time.

    `readonly=True` opens an existing file for reading only (the export), never creating
    or migrating it.
    """

    def __init__(self, path: str | Path, *, readonly: bool = False) -> None:
        self.path = Path(path)
        if readonly and not self.path.is_file():
            raise ValueError(
                f"DB {str(self.path)!r} does not exist; expected a study database ({DB_FILE}) or the study folder holding it"
            )
        if self.path.is_dir():
            raise ValueError(f"{str(self.path)!r} is a folder; expected a study database file")
        stamped = header_version(self.path)
        if stamped is not None and stamped > SCHEMA_VERSION:
            raise newer_schema_error(self.path, stamped)
        if not readonly:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        uri = f"file:{self.path.resolve()}?mode=ro" if readonly else str(self.path)
        try:
            self._db = sqlite3.connect(uri, uri=readonly, isolation_level=None, check_same_thread=False, timeout=10)
            self._db.row_factory = sqlite3.Row
            self._db.execute("PRAGMA foreign_keys = ON")
            if not readonly:
                self._db.execute("PRAGMA journal_mode = WAL")
                self._db.execute("PRAGMA synchronous = FULL")
            version = self._db.execute("PRAGMA user_version").fetchone()[0]
        except sqlite3.DatabaseError as exc:
            raise ValueError(f"{str(self.path)!r} is not a study database ({exc})") from None
        self._lock = threading.RLock()
        if version > SCHEMA_VERSION:  # a newer version only in the WAL, which the header check cannot see
            self._db.close()
            raise newer_schema_error(self.path, version)
        if version < SCHEMA_VERSION:
            if readonly:
                raise ValueError(
                    f"{str(self.path)!r} has schema version {version}; open it once with `rllib-conv play` to migrate it to {SCHEMA_VERSION}"
                )
            self._migrate(version)

    def _migrate(self, version: int) -> None:
        with self._write() as db:
            for v in range(version, SCHEMA_VERSION):
                for statement in MIGRATIONS[v].split(";"):
                    if statement.strip():
                        db.execute(statement)
            db.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")

    @contextmanager
    def _write(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: committed when the block ends, rolled back whole if it raises."""
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield self._db
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
            try:
                self._db.execute("COMMIT")
            except sqlite3.Error:
                if self._db.in_transaction:
                    self._db.execute("ROLLBACK")
                raise

    def _read(self, sql: str, params: tuple | dict = ()) -> list[sqlite3.Row]:
        with self._lock:
            return self._db.execute(sql, params).fetchall()

    def close(self) -> None:
        """Close the connection (a WAL checkpoint folds the log into the file)."""
        with self._lock:
            self._db.close()

    # -- one study per file -------------------------------------------------------------
    def check_settings(self, settings: Mapping[str, Any], conditions: Mapping[str, tuple[str, str]]) -> None:
        """Record `settings` and `conditions` (name -> (kind, description)) on first use; refuse different ones later.

        A setting that differs from the stored one raises ValueError naming it. A stored
        condition may be left out only when none of its participants is still waiting or
        playing (their sessions could not be restored); one with the same name must keep
        its kind and description.
        """
        stored = self.settings()
        for key, value in settings.items():
            if key in stored and stored[key] != str(value):
                raise ValueError(
                    f"the study in {str(self.path)!r} was started with {key} {stored[key]}, not {value}; use the same setting or another study folder"
                )
        old = {r["name"]: (r["kind"], r["description"]) for r in self._read("SELECT name, kind, description FROM conditions")}
        for name, (kind, description) in conditions.items():
            if name in old and old[name] != (kind, description):
                raise ValueError(
                    f"condition {name!r} of the study in {str(self.path)!r} was {old[name][1]!r}, now {description!r}; "
                    "give it the same agent and settings, or another name"
                )
        for name in sorted(set(old) - set(conditions)):
            open_ = self._read(
                "SELECT COUNT(*) FROM participants WHERE condition = ? AND state IN ('waiting', 'playing')", (name,)
            )[0][0]
            if open_:
                raise ValueError(
                    f"condition {name!r} of the study in {str(self.path)!r} has {open_} unfinished session(s); keep it in --conditions until they end"
                )
        with self._write() as db:
            db.executemany(
                "INSERT OR IGNORE INTO settings (key, value) VALUES (?, ?)", [(k, str(v)) for k, v in settings.items()]
            )
            db.executemany(
                "INSERT OR IGNORE INTO conditions (name, kind, description) VALUES (?, ?, ?)",
                [(n, k, d) for n, (k, d) in conditions.items()],
            )

    def count_start(self) -> int:
        """Count one more server start on this database; return how many there have been (1 for a new study)."""
        with self._write() as db:
            row = db.execute("SELECT value FROM settings WHERE key = 'starts'").fetchone()
            starts = int(row[0]) + 1 if row else 1
            db.execute("INSERT OR REPLACE INTO settings (key, value) VALUES ('starts', ?)", (str(starts),))
            return starts

    def count_refused_resume(self) -> int:
        """Count one more refused re-enrolment (an id sent without its token); return the total."""
        with self._write() as db:
            row = db.execute("SELECT value FROM settings WHERE key = 'refused_resumes'").fetchone()
            total = int(row[0]) + 1 if row else 1
            db.execute("INSERT OR REPLACE INTO settings (key, value) VALUES ('refused_resumes', ?)", (str(total),))
            return total

    def refused_resumes(self) -> int:
        """How many re-enrolments without the participant's token were refused in this study."""
        row = self._read("SELECT value FROM settings WHERE key = 'refused_resumes'")
        return int(row[0][0]) if row else 0

    def settings(self) -> dict[str, str]:
        """The study's stored settings (game, seed, ...) as text; empty for a new file."""
        return {r["key"]: r["value"] for r in self._read("SELECT key, value FROM settings")}

    def condition_descriptions(self) -> dict[str, tuple[str, str]]:
        """Every condition ever run in this study: name -> (kind, description)."""
        return {
            r["name"]: (r["kind"], r["description"])
            for r in self._read("SELECT name, kind, description FROM conditions ORDER BY rowid")
        }

    # -- participants and rooms ----------------------------------------------------------
    def add_participant(self, p: Participant) -> None:
        """Insert a new participant (sqlite3.IntegrityError if the id is taken)."""
        with self._write() as db:
            db.execute(
                "INSERT INTO participants (id, token, condition, state, created, updated) VALUES (?, ?, ?, ?, ?, ?)",
                (p.id, p.token, p.condition, p.state, p.created, p.updated),
            )

    def participants(self) -> list[Participant]:
        """Every participant, in the order they arrived."""
        return [Participant(**dict(r)) for r in self._read("SELECT * FROM participants ORDER BY created, rowid")]

    def open_room(self, game: str, condition: str, agent_seat: int | None, seats: Mapping[int, str], now: float) -> int:
        """Create a room and seat its participants (seat -> participant id) in one transaction; return its pair number."""
        with self._write() as db:
            pair = db.execute(
                "INSERT INTO rooms (game, condition, agent_seat, state, created, updated) VALUES (?, ?, ?, 'playing', ?, ?)",
                (game, condition, agent_seat, now, now),
            ).lastrowid
            for seat, pid in seats.items():
                db.execute(
                    "UPDATE participants SET pair = ?, seat = ?, state = 'playing', updated = ? WHERE id = ?",
                    (pair, seat, now, pid),
                )
            return int(pair)

    def close_room(self, pair: int | None, state: str, reason: str | None, codes: Mapping[str, str], now: float) -> None:
        """End room `pair` (None: no room, e.g. a participant who never got a partner) and its participants.

        `state` is "finished" (played to the end) or "ended" (`reason`: why it stopped);
        `codes` maps each participant to end to their completion code.
        """
        if state not in ("finished", "ended"):
            raise ValueError(f"state must be 'finished' or 'ended', got {state!r}")
        with self._write() as db:
            if pair is not None:
                db.execute("UPDATE rooms SET state = ?, end_reason = ?, updated = ? WHERE pair = ?", (state, reason, now, pair))
            db.executemany(
                "UPDATE participants SET state = ?, end_reason = ?, completion_code = ?, updated = ? WHERE id = ?",
                [(state, reason, code, now, pid) for pid, code in codes.items()],
            )

    def rooms(self, states: tuple[str, ...] = ROOM_STATES) -> list[RoomRecord]:
        """The rooms in `states`, oldest first."""
        marks = ",".join("?" * len(states))
        return [RoomRecord(**dict(r)) for r in self._read(f"SELECT * FROM rooms WHERE state IN ({marks}) ORDER BY pair", states)]

    # -- what is played --------------------------------------------------------------------
    def add_pick(self, pair: int, step: int, seat: int, action: int, now: float) -> None:
        """Record a person's pick in try `step` before the partner has picked."""
        with self._write() as db:
            db.execute("INSERT INTO picks (pair, step, seat, action, at) VALUES (?, ?, ?, ?, ?)", (pair, step, seat, action, now))
            db.execute("UPDATE rooms SET updated = ? WHERE pair = ?", (now, pair))

    def add_try(self, pair: int, step: int, row: Mapping[str, Any], prize: float, now: float) -> None:
        """Record finished bandit try `step` of room `pair` (`row`: task, context, try, action_1, action_2; 1-based arms)."""
        with self._write() as db:
            db.execute(
                "INSERT INTO tries (pair, step, task, context, try, action_1, action_2, prize, at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (pair, step, row["task"], row["context"], row["try"], row["action_1"], row["action_2"], prize, now),
            )
            db.execute("UPDATE rooms SET updated = ? WHERE pair = ?", (now, pair))

    def add_move(
        self,
        pair: int,
        step: int,
        game: int,
        move: int,
        player: int,
        action: int,
        now: float,
        result: tuple[int, int, int] | None = None,
    ) -> None:
        """Record blocks move `step` of room `pair`; `result` (red goal, blue goal, score) when it ends game `game`."""
        with self._write() as db:
            db.execute(
                "INSERT INTO moves (pair, step, game, move, player, action, at) VALUES (?, ?, ?, ?, ?, ?, ?)",
                (pair, step, game, move, player, action, now),
            )
            if result is not None:
                db.execute(
                    "INSERT INTO games (pair, game, red_goal, blue_goal, score) VALUES (?, ?, ?, ?, ?)", (pair, game, *result)
                )
            db.execute("UPDATE rooms SET updated = ? WHERE pair = ?", (now, pair))

    def picks(self, pair: int) -> list[sqlite3.Row]:
        """Every pick of room `pair` (step, seat, action), in order."""
        return self._read("SELECT step, seat, action FROM picks WHERE pair = ? ORDER BY step, at", (pair,))

    def tries(self, pair: int | None = None, condition: str | None = None) -> list[sqlite3.Row]:
        """Finished bandit tries (of one room or condition, or all), ordered by pair and step, with their room's condition."""
        sql = "SELECT t.*, r.condition FROM tries t JOIN rooms r USING (pair) WHERE (? IS NULL OR t.pair = ?) AND (? IS NULL OR r.condition = ?) ORDER BY t.pair, t.step"
        return self._read(sql, (pair, pair, condition, condition))

    def moves(self, pair: int | None = None, condition: str | None = None) -> list[sqlite3.Row]:
        """Blocks moves (of one room or condition, or all) with their game's result where it ended, ordered by pair and step."""
        sql = (
            "SELECT m.*, g.red_goal, g.blue_goal, g.score, r.condition FROM moves m JOIN rooms r USING (pair) "
            "LEFT JOIN games g ON g.pair = m.pair AND g.game = m.game "
            "WHERE (? IS NULL OR m.pair = ?) AND (? IS NULL OR r.condition = ?) ORDER BY m.pair, m.step"
        )
        return self._read(sql, (pair, pair, condition, condition))

    def counts(self) -> dict[str, dict[str, int]]:
        """Per condition: participants per state, rooms, finished tries and moves."""
        out: dict[str, dict[str, int]] = {
            name: {s: 0 for s in PARTICIPANT_STATES} | {"rooms": 0, "tries": 0, "moves": 0}
            for name in self.condition_descriptions()
        }
        for r in self._read("SELECT condition, state, COUNT(*) AS n FROM participants GROUP BY condition, state"):
            out[r["condition"]][r["state"]] = r["n"]
        for r in self._read("SELECT condition, COUNT(*) AS n FROM rooms GROUP BY condition"):
            out[r["condition"]]["rooms"] = r["n"]
        for table in ("tries", "moves"):
            for r in self._read(
                f"SELECT r.condition, COUNT(*) AS n FROM {table} t JOIN rooms r USING (pair) GROUP BY r.condition"
            ):
                out[r["condition"]][table] = r["n"]
        return out
