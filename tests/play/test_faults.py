"""Faults and load on the real `rllib-conv play` (loopback): SIGKILL mid-session and a restart, many participants at once.

Simulated participants (`rllib_conv.play.simulated`) play whole 30-try sessions, half with
the agent and half in human pairs. What each was shown as played is checked against the
database: every acknowledged try is there, exactly once, with the arms shown.
"""

from __future__ import annotations

import asyncio
import signal
import sqlite3
import time
from pathlib import Path

from rllib_conv.play.simulated import Outcome, audit, simulate
from rllib_conv.play.store import DB_FILE
from tests.play.servers import StudyProcess

TRIES = 30
ARGS = ["--agent", "agent=oracle", "--conditions", "agent,human", "--enrol-limit", "0"]  # every participant comes from loopback


def stored_tries(db: Path) -> int:
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as raw:
        return raw.execute("SELECT COUNT(*) FROM tries").fetchone()[0]


def check(db: Path, outcomes: list[Outcome], pairs: int, before_outage: bool = False) -> None:
    """Every participant finished with a code in their own session; nothing they were shown lost; nothing stored twice."""
    result = audit(db, outcomes, before_outage)
    assert (result.lost, result.duplicated, result.unfinished, result.new_tokens) == (0, 0, 0, 0), result
    assert (result.pairs, result.tries) == (pairs, pairs * TRIES), result
    assert all(len(o.seen) == TRIES for o in outcomes)


def test_a_server_killed_mid_session_loses_nothing_and_everyone_resumes(study_process, tmp_path: Path) -> None:
    out = tmp_path / "study"
    server = study_process([*ARGS, "--port", "0", "--out", str(out)])
    db = out / DB_FILE
    ids = [f"k{i}" for i in range(8)]  # 4 with the agent, 2 human pairs
    restarted: list[StudyProcess] = []

    async def kill_and_restart() -> None:
        deadline = time.monotonic() + 60
        while stored_tries(db) < 60 and time.monotonic() < deadline:
            await asyncio.sleep(0.02)
        server.kill()  # SIGKILL: mid-session, requests in flight
        assert 60 <= stored_tries(db) < TRIES * 6
        restarted.append(await asyncio.to_thread(study_process, [*ARGS, "--port", str(server.port), "--out", str(out)]))

    outcomes = asyncio.run(simulate(server.url, ids, during=kill_and_restart))
    assert restarted and all(o.seen_before_outage for o in outcomes)  # every one of them lost the server mid-session
    check(db, outcomes, 6, before_outage=True)  # what they were shown before the kill: 4 agent rooms, 2 human pairs
    check(db, outcomes, 6)
    assert restarted[0].interrupt() == 130  # Ctrl-C: a graceful stop, then the usual status of an interrupt


def test_many_participants_at_once_all_finish_with_nothing_lost_or_doubled(study_process, tmp_path: Path) -> None:
    out = tmp_path / "study"
    server = study_process([*ARGS, "--port", "0", "--out", str(out)])
    outcomes = asyncio.run(simulate(server.url, [f"n{i}" for i in range(24)]))  # benchmarks/study_server.py runs 100
    assert sorted(o.partner for o in outcomes).count("agent") == 12
    check(out / DB_FILE, outcomes, 12 + 6)
    o = outcomes[0]
    key = next(iter(o.seen))
    o.seen[key] = (o.seen[key][0] % 4 + 1, o.seen[key][1])  # were a try shown with another arm than stored,
    assert audit(out / DB_FILE, outcomes).lost == 1  # the audit would say so
    assert server.interrupt() == 130


def test_ctrl_c_stops_the_server_even_when_the_caller_ignores_it(study_process, tmp_path: Path) -> None:
    # A shell's background job (`nohup make test &`, as CI may run) starts with SIGINT ignored, which children inherit.
    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        server = study_process([*ARGS, "--port", "0", "--out", str(tmp_path / "study")])
    finally:
        signal.signal(signal.SIGINT, before)
    assert server.interrupt() == 130
