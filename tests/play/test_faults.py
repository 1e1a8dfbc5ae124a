"""Faults and load on the real `rllib-conv play` (loopback): SIGKILL mid-session and a restart, many participants at once.

Simulated participants (`rllib_conv.play.simulated`) play whole 30-try sessions, half with
the agent and half in human pairs. What each was shown as played is checked against the
database: every acknowledged try is there, exactly once, with the arms shown.
"""

from __future__ import annotations

import asyncio
import sqlite3
import time
from pathlib import Path

import httpx

from rllib_conv.play.simulated import Outcome, Participant
from rllib_conv.play.store import DB_FILE, Store
from tests.play.servers import StudyProcess

TRIES = 30
ARGS = ["--agent", "agent=oracle", "--conditions", "agent,human"]


def stored_tries(db: Path) -> int:
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as raw:
        return raw.execute("SELECT COUNT(*) FROM tries").fetchone()[0]


def check_against_the_database(db: Path, outcomes: list[Outcome], acknowledged: dict[str, dict] | None = None) -> None:
    """Every session complete, every try each participant saw stored once with the arms it saw."""
    store = Store(db, readonly=True)
    seats = {p.id: (p.pair, p.seat) for p in store.participants()}
    rows: dict[int, dict] = {}
    for r in store.tries():
        rows.setdefault(r["pair"], {})[(r["task"], r["context"], r["try"])] = (r["action_1"], r["action_2"], r["step"])
    store.close()
    assert all(len(tries) == TRIES and sorted(s for *_, s in tries.values()) == list(range(TRIES)) for tries in rows.values())  # none lost, none twice
    for o in outcomes:
        assert o.phase == "finished" and o.completion_code and len(o.tokens) == 1, (o.participant, o.phase, o.tokens)
        pair, seat = seats[o.participant]
        shown = acknowledged[o.participant] if acknowledged else o.seen
        assert len(o.seen) == TRIES
        for key, (you, partner) in shown.items():
            a1, a2, _ = rows[pair][key]
            assert (you, partner) == ((a1, a2) if seat == 1 else (a2, a1)), (o.participant, key)


async def play_all(url: str, ids: list[str], watcher=None) -> list[Outcome]:
    limits = httpx.Limits(max_connections=len(ids) + 10)
    async with httpx.AsyncClient(limits=limits, timeout=httpx.Timeout(10.0)) as client:
        people = [Participant(client, url, pid, deadline_s=120) for pid in ids]
        tasks = [asyncio.ensure_future(p.play()) for p in people]
        if watcher is not None:
            await watcher(people)
        return list(await asyncio.gather(*tasks))


def test_a_server_killed_mid_session_loses_nothing_and_everyone_resumes(study_process, tmp_path: Path) -> None:
    out = tmp_path / "study"
    server = study_process([*ARGS, "--port", "0", "--out", str(out)])
    db = out / DB_FILE
    ids = [f"k{i}" for i in range(8)]  # 4 with the agent, 2 human pairs
    acknowledged: dict[str, dict] = {}
    restarted: list[StudyProcess] = []

    async def kill_and_restart(people: list[Participant]) -> None:
        deadline = time.monotonic() + 60
        while stored_tries(db) < 60 and time.monotonic() < deadline:
            await asyncio.sleep(0.02)
        server.kill()  # SIGKILL: mid-session, requests in flight
        acknowledged.update({p.out.participant: dict(p.out.seen) for p in people})
        before = stored_tries(db)
        assert 60 <= before < TRIES * 6
        restarted.append(await asyncio.to_thread(study_process, [*ARGS, "--port", str(server.port), "--out", str(out)]))

    outcomes = asyncio.run(play_all(server.url, ids, kill_and_restart))
    assert restarted and sum(len(a) for a in acknowledged.values()) > 0
    check_against_the_database(db, outcomes, acknowledged)
    check_against_the_database(db, outcomes)
    assert sum(o.reconnects for o in outcomes) > 0  # they did lose the server
    assert restarted[0].interrupt() == 130  # Ctrl-C: a graceful stop, then the usual status of an interrupt


def test_many_participants_at_once_all_finish_with_nothing_lost_or_doubled(study_process, tmp_path: Path) -> None:
    out = tmp_path / "study"
    server = study_process([*ARGS, "--port", "0", "--out", str(out)])
    outcomes = asyncio.run(play_all(server.url, [f"n{i}" for i in range(24)]))  # benchmarks/study_server.py runs 100
    assert sorted(o.partner for o in outcomes).count("agent") == 12
    check_against_the_database(out / DB_FILE, outcomes)
    assert server.interrupt() == 130
