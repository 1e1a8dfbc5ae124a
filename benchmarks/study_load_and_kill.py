"""Load and a kill in one run: 100 participants play the bandit study, the server gets SIGKILL mid-study and restarts.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.study_load_and_kill [--participants 100] [--think 0.5]
        [--kill-at 0.33] [--clients 2] [--name study_load_and_kill]

`--participants` simulated participants (rllib_conv.play.simulated) enrol at once and play
whole 30-try sessions, half with the (oracle) agent and half in human pairs, thinking
~`--think` s before each pick. When the database holds `--kill-at` of the study's tries the
server (the real `rllib-conv play`) gets SIGKILL and is started again on the same database
and port; the participants resume with their id and the token their first enrolment gave
(as the page does). Then every participant's id is sent once more without its token: each
must be refused (409), never handed the session.

Reported: p50/p99/max latency per request kind as the participants saw it (the retries
that found no server are not requests answered; the outage is reported on its own), the
outage (kill to the restarted server's first answer), and the audit: tries acknowledged
before the kill and kept, tries lost or duplicated in the end, sessions resumed (the same
token after the restart) and unfinished, takeovers refused. Prints a table; writes
results/<name>.json with the machine (CPU model) recorded. About a minute on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import httpx

from benchmarks._common import write_result
from benchmarks.study_server import TRIES, cpu_s, latencies, run_clients, server_args, stored_tries
from rllib_conv.play.simulated import ServerProcess, audit
from rllib_conv.play.store import DB_FILE

ADMIN = {"Authorization": "Bearer benchmark-token"}


def wait_until_answering(url: str) -> None:
    while True:
        try:
            httpx.get(url + "api/info", timeout=1).raise_for_status()
            return
        except httpx.HTTPError:
            time.sleep(0.01)


def load_and_kill(n: int, clients: int, think_s: float, kill_at: float, root: Path) -> dict:
    """One study: `n` participants, a SIGKILL when `kill_at` of its tries are stored, a restart, the audit."""
    out = root / "study"
    db = out / DB_FILE
    total = (n // 2 + n // 4) * TRIES  # n/2 agent rooms and n/4 human pairs
    server = ServerProcess(server_args(out, None))
    restarted: list[ServerProcess] = []
    marks: dict[str, float] = {}

    def kill_and_restart() -> None:
        while stored_tries(db) < kill_at * total:
            time.sleep(0.01)
        marks["cpu_before_kill"] = cpu_s(server.proc.pid)
        server.kill()
        marks["killed"] = time.perf_counter()
        marks["tries_at_kill"] = stored_tries(db)
        restarted.append(ServerProcess(server_args(out, None, server.port)))
        wait_until_answering(server.url)
        marks["back"] = time.perf_counter()

    ids = [f"p{i:03d}" for i in range(n)]
    try:
        start = time.perf_counter()
        outcomes = run_clients(server.url, ids, clients, deadline_s=300, think_s=think_s, during=kill_and_restart)
        wall = time.perf_counter() - start
        with httpx.Client(base_url=server.url, timeout=10) as c:
            takeovers = [c.post("/api/participants", json={"consent": True, "participant": pid}) for pid in ids]
            status = c.get("/api/admin/status", headers=ADMIN).json()
        server_cpu = marks["cpu_before_kill"] + cpu_s(restarted[0].proc.pid)
        before, after = audit(db, outcomes, before_outage=True), audit(db, outcomes)
        restarted[0].interrupt()
    finally:
        server.close()
        for proc in restarted:
            proc.close()
    tokens = {o.participant: next(iter(o.tokens)) for o in outcomes if len(o.tokens) == 1}
    acknowledged = sum(len(o.seen_before_outage or {}) for o in outcomes)  # per participant: a pair's try counts twice
    return {
        "participants": n,
        "think_s": think_s,
        "clients": clients,
        "with_agent": sum(o.partner == "agent" for o in outcomes),
        "in_human_pairs": sum(o.partner == "person" for o in outcomes),
        "wall_s": round(wall, 2),
        "tries": after.tries,
        "tries_per_s": round(after.tries / wall, 1),
        "server_cpu_s": round(server_cpu, 2),  # both servers, their startups included
        "latency": latencies(outcomes),
        "kill": {
            "tries_at_kill": int(marks["tries_at_kill"]),
            "of_total": total,
            "outage_s": round(marks["back"] - marks["killed"], 2),
            "participants_who_saw_it": sum(o.seen_before_outage is not None for o in outcomes),
        },
        "audit": {
            "acknowledged_before_kill": acknowledged,
            "acknowledged_kept": acknowledged - before.lost,
            "lost_before_kill": before.lost,
            "lost": after.lost,
            "duplicated": after.duplicated,
            "unfinished": after.unfinished,
            "finished": after.finished,
            "resumes": sum(o.resumes for o in outcomes),
            "resumed_same_session": sum(len(o.tokens) == 1 and o.seen_before_outage is not None for o in outcomes),
            "new_sessions_on_resume": after.new_tokens,
            "refused_resumes_seen_by_participants": sum(o.refused_resumes for o in outcomes),
            "conflicts_409": sum(o.conflicts for o in outcomes),
        },
        "takeover": {
            "attempts": len(takeovers),
            "refused_409": sum(r.status_code == 409 for r in takeovers),
            "token_handed_out": sum(r.status_code == 200 or any(t in r.text for t in tokens.values()) for r in takeovers),
            "admin_refused_resumes": status.get("refused_resumes"),
        },
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--participants", type=int, default=100, help="simulated participants (default 100; a multiple of 4)")
    p.add_argument("--think", type=float, default=0.5, help="mean seconds a participant thinks before a pick (default 0.5)")
    p.add_argument(
        "--kill-at", type=float, default=0.33, help="SIGKILL when this share of the study's tries is stored (default 0.33)"
    )
    p.add_argument("--clients", type=int, default=2, help="client processes (default 2)")
    p.add_argument("--name", default="study_load_and_kill", help="result file name under benchmarks/results/")
    args = p.parse_args()
    if args.participants < 4 or args.participants % 4:
        p.error(f"--participants must be a positive multiple of 4 (half with the agent, half in pairs), got {args.participants}")
    if not 0 < args.kill_at < 1:
        p.error(f"--kill-at must be between 0 and 1, got {args.kill_at}")
    if args.clients < 1 or args.think < 0:
        p.error("--clients must be at least 1 and --think at least 0")
    loadavg = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="study-kill-") as tmp:
        r = load_and_kill(args.participants, args.clients, args.think, args.kill_at, Path(tmp))
    print(f"{'request':<10}{'n':>7}{'p50 ms':>10}{'p99 ms':>10}{'max ms':>10}")
    for kind, s in r["latency"].items():
        print(f"{kind:<10}{s['n']:>7}{s['p50_ms']:>10}{s['p99_ms']:>10}{s['max_ms']:>10}")
    k, a, t = r["kill"], r["audit"], r["takeover"]
    rows = [
        (
            "participants",
            f"{r['participants']} ({r['with_agent']} with the agent, {r['in_human_pairs']} in human pairs), thinking ~{r['think_s']:g} s",
        ),
        ("study", f"{r['tries']} tries in {r['wall_s']} s ({r['tries_per_s']} tries/s), server CPU {r['server_cpu_s']} s"),
        ("SIGKILL", f"at {k['tries_at_kill']} of {k['of_total']} tries stored; back in {k['outage_s']} s"),
        ("acknowledged kept", f"{a['acknowledged_kept']} of {a['acknowledged_before_kill']} (lost {a['lost_before_kill']})"),
        ("in the end", f"lost {a['lost']}, duplicated {a['duplicated']}, finished {a['finished']}, unfinished {a['unfinished']}"),
        (
            "resumed",
            f"{a['resumed_same_session']} participants in their own session ({a['resumes']} resumes), "
            f"{a['new_sessions_on_resume']} new sessions, {a['refused_resumes_seen_by_participants']} refused",
        ),
        (
            "takeover by id",
            f"{t['refused_409']} of {t['attempts']} refused (409), {t['token_handed_out']} tokens handed out; admin page counts {t['admin_refused_resumes']}",
        ),
    ]
    for name, text in rows:
        print(f"{name:<20}{text}")
    path = write_result(args.name, {**r, "loadavg_at_start": loadavg})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
