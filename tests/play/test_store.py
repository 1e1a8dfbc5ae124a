"""The study database: WAL and a versioned schema, whole transactions, one study per file."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from rllib_conv.play.store import DB_FILE, SCHEMA_VERSION, Participant, Store, db_path

SETTINGS = {"game": "bandit", "seed": 0, "tries": 5}
CONDITIONS = {"agent": ("agent", "oracle, step 3"), "human": ("human", "two participants")}


@pytest.fixture
def store(tmp_path: Path):
    s = Store(tmp_path / DB_FILE)
    s.check_settings(SETTINGS, CONDITIONS)
    yield s
    s.close()


def test_a_new_file_is_wal_with_the_current_schema_version(store: Store) -> None:
    raw = sqlite3.connect(store.path)
    assert raw.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert raw.execute("PRAGMA user_version").fetchone()[0] == SCHEMA_VERSION
    tables = {r[0] for r in raw.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    assert {"settings", "conditions", "participants", "rooms", "picks", "tries", "moves", "games"} <= tables
    assert db_path(store.path.parent) == store.path and db_path(store.path) == store.path


def test_a_newer_schema_or_a_foreign_file_is_refused(tmp_path: Path) -> None:
    newer = tmp_path / "newer.sqlite3"
    raw = sqlite3.connect(newer)
    raw.execute(f"PRAGMA user_version = {SCHEMA_VERSION + 1}")
    raw.close()
    with pytest.raises(ValueError, match=f"schema version {SCHEMA_VERSION + 1}, newer than this release's {SCHEMA_VERSION}"):
        Store(newer)
    junk = tmp_path / "junk.sqlite3"
    junk.write_bytes(b"this is not a database" * 100)
    with pytest.raises(ValueError, match="is not a study database"):
        Store(junk)
    with pytest.raises(ValueError, match="does not exist"):
        Store(tmp_path / "missing.sqlite3", readonly=True)


def test_written_rows_are_committed_and_visible_to_another_connection(store: Store) -> None:
    store.add_participant(Participant("p1", "tok", "agent", created=1.0, updated=1.0))
    pair = store.open_room("bandit", "agent", 1, {2: "p1"}, 2.0)
    store.add_try(pair, 0, {"task": "train", "context": "A", "try": 1, "action_1": 1, "action_2": 1}, 1.0, 3.0)
    other = Store(store.path, readonly=True)  # what a crash would leave: only committed rows
    assert [(p.id, p.pair, p.seat, p.state) for p in other.participants()] == [("p1", pair, 2, "playing")]
    assert [(r["step"], r["action_1"], r["condition"]) for r in other.tries()] == [(0, 1, "agent")]
    assert other.counts()["agent"] == {"waiting": 0, "playing": 1, "finished": 0, "ended": 0, "rooms": 1, "tries": 1, "moves": 0}
    other.close()


def test_a_failed_transaction_leaves_nothing_behind(store: Store) -> None:
    store.add_participant(Participant("p1", "tok", "human", created=1.0, updated=1.0))
    store.add_participant(Participant("p2", "tok2", "human", created=1.0, updated=1.0))
    pair = store.open_room("bandit", "human", None, {1: "p1", 2: "p2"}, 2.0)
    row = {"task": "train", "context": "A", "try": 1, "action_1": 1, "action_2": 2}
    store.add_try(pair, 0, row, 0.0, 3.0)
    with pytest.raises(sqlite3.IntegrityError):
        store.add_try(pair, 1, row, 0.0, 4.0)  # the same (task, context, try) again: never a duplicated try
    with pytest.raises(sqlite3.IntegrityError):
        store.add_try(pair, 1, row | {"try": 2, "action_1": 9}, 0.0, 4.0)  # an arm out of range
    with pytest.raises(sqlite3.IntegrityError):
        store.add_participant(Participant("p1", "t3", "human"))  # an id is enrolled once
    assert [r["step"] for r in store.tries(pair)] == [0]
    assert store.rooms()[0].updated == 3.0  # the failed writes did not touch the room either


def test_a_restart_with_other_settings_or_conditions_is_refused(store: Store) -> None:
    with pytest.raises(ValueError, match="was started with seed 0, not 7"):
        store.check_settings(SETTINGS | {"seed": 7}, CONDITIONS)
    with pytest.raises(ValueError, match="condition 'agent' .* was 'oracle, step 3', now 'oracle, step 5'"):
        store.check_settings(SETTINGS, {"agent": ("agent", "oracle, step 5")})
    store.add_participant(Participant("p1", "tok", "human", created=1.0, updated=1.0))
    with pytest.raises(ValueError, match="condition 'human' .* has 1 unfinished session"):
        store.check_settings(SETTINGS, {"agent": CONDITIONS["agent"]})
    store.check_settings(SETTINGS, CONDITIONS | {"baseline": ("agent", "another ego")})  # a new condition may join
    assert list(store.condition_descriptions()) == ["agent", "human", "baseline"]
