"""Load and faults of the study server (`rllib-conv play`), on loopback, with simulated participants.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.study_server [--participants 100] [--clients 2]
        [--fault-participants 20] [--run RUN]

- load: `--participants` simulated participants (rllib_conv.play.simulated) enrol at once
  and play whole 30-try bandit sessions, half with the agent and half in human pairs
  (balanced assignment), twice: as fast as the server answers (its throughput; latency is
  then mostly queueing) and thinking ~`--think` s before each pick (closer to people);
  `--clients` processes run them.
  Measured: wall time, tries per second, p50/p99 latency of each request kind as the
  participants saw it (enrol, move, session), and the audit of the database against what
  they were shown (lost, duplicated, unfinished).
- faults: `--fault-participants` play; after a third of their tries the server gets
  SIGKILL and is started again on the same database and port; they resume by id.
  Measured: tries stored at the kill, the outage (kill to the first answer of the new
  server), and the audit against what each was shown before the outage.

The server's agent is the oracle agent unless `--run` gives a trained ego (then each of
its picks is a forward pass of the task module). Clients and server share the machine's
cores: the latencies include the clients' own queueing and are an upper bound for one
server on this machine; the server's CPU time says how much of the wall time it worked. Prints a table; writes results/study_server.json.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sqlite3
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import httpx
import numpy as np

from benchmarks._common import write_result
from rllib_conv.play.simulated import Outcome, ServerProcess, audit, simulate
from rllib_conv.play.store import DB_FILE

TRIES = 30


def play_slice(url: str, ids: list[str], deadline_s: float, think_s: float) -> list[Outcome]:
    """One client process: its participants, all at once."""
    return asyncio.run(simulate(url, ids, deadline_s=deadline_s, think_s=think_s))


def run_clients(url: str, ids: list[str], clients: int, deadline_s: float, think_s: float = 0.0, during=None) -> list[Outcome]:
    """Play `ids` from `clients` processes (their slices interleaved); `during()` runs in this process meanwhile."""
    with ProcessPoolExecutor(clients) as pool:
        futures = [pool.submit(play_slice, url, ids[k::clients], deadline_s, think_s) for k in range(clients)]
        if during is not None:
            during()
        return [o for f in futures for o in f.result()]


def latencies(outcomes: list[Outcome]) -> dict[str, dict[str, float]]:
    """p50, p99 and max latency in ms, and the count, per request kind."""
    kinds = sorted({k for o in outcomes for k in o.latencies})
    out = {}
    for kind in kinds:
        ms = np.array([x for o in outcomes for x in o.latencies.get(kind, [])]) * 1000
        out[kind] = {
            "n": int(ms.size),
            "p50_ms": round(float(np.percentile(ms, 50)), 2),
            "p99_ms": round(float(np.percentile(ms, 99)), 2),
            "max_ms": round(float(ms.max()), 2),
        }
    return out


def server_args(out: Path, run: str | None, port: int = 0) -> list[str]:
    agent = [run] if run else ["--agent", "agent=oracle"]
    # Every simulated participant comes from loopback: one client address, so no enrolment limit.
    return [
        *agent,
        "--conditions",
        "agent,human",
        "--port",
        str(port),
        "--out",
        str(out),
        "--admin-token",
        "benchmark-token",
        "--enrol-limit",
        "0",
    ]


def cpu_s(pid: int) -> float:
    """CPU seconds (user + system) process `pid` has used so far (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def stored_tries(db: Path) -> int:
    with sqlite3.connect(f"file:{db}?mode=ro", uri=True) as raw:
        return raw.execute("SELECT COUNT(*) FROM tries").fetchone()[0]


def load(n: int, clients: int, run: str | None, root: Path, think_s: float) -> dict:
    out = root / f"load-think{think_s:g}"
    server = ServerProcess(server_args(out, run))
    try:
        start = time.perf_counter()
        outcomes = run_clients(server.url, [f"load-{i}" for i in range(n)], clients, deadline_s=600, think_s=think_s)
        wall = time.perf_counter() - start
        server_cpu = cpu_s(server.proc.pid)
        result = audit(out / DB_FILE, outcomes)
        server.interrupt()
    finally:
        server.close()
    return {
        "participants": n,
        "think_s": think_s,
        "with_agent": sum(o.partner == "agent" for o in outcomes),
        "in_human_pairs": sum(o.partner == "person" for o in outcomes),
        "wall_s": round(wall, 2),
        "tries_per_s": round(result.tries / wall, 1),
        "server_cpu_s": round(server_cpu, 2),  # startup included; the rest of the wall time the server waited on its clients
        "server_cpu_ms_per_try": round(server_cpu / result.tries * 1000, 2),
        "latency": latencies(outcomes),
        "reconnects": sum(o.reconnects for o in outcomes),
        "audit": vars(result),
    }


def faults(n: int, clients: int, run: str | None, root: Path) -> dict:
    out = root / "faults"
    db = out / DB_FILE
    server = ServerProcess(server_args(out, run))
    restarted: list[ServerProcess] = []
    marks: dict[str, float] = {}

    def kill_and_restart() -> None:
        target = (n // 2 + n // 4) * TRIES // 3  # a third of all tries: n/2 agent rooms and n/4 human pairs
        while stored_tries(db) < target:
            time.sleep(0.01)
        server.kill()
        marks["killed"] = time.perf_counter()
        marks["tries_at_kill"] = stored_tries(db)
        restarted.append(ServerProcess(server_args(out, run, server.port)))
        while True:
            try:
                httpx.get(server.url + "api/info", timeout=1).raise_for_status()
                break
            except httpx.HTTPError:
                time.sleep(0.01)
        marks["back"] = time.perf_counter()

    try:
        outcomes = run_clients(server.url, [f"fault-{i}" for i in range(n)], clients, deadline_s=600, during=kill_and_restart)
        before, after = audit(db, outcomes, before_outage=True), audit(db, outcomes)
        restarted[0].interrupt()
    finally:
        server.close()
        for proc in restarted:
            proc.close()
    return {
        "participants": n,
        "tries_at_kill": int(marks["tries_at_kill"]),
        "acknowledged_before_kill": sum(
            len(o.seen_before_outage or {}) for o in outcomes
        ),  # per participant: a pair's try counts twice
        "outage_s": round(marks["back"] - marks["killed"], 2),
        "resumed_same_session": sum(len(o.tokens) == 1 for o in outcomes),
        "audit_before_kill": vars(before),
        "audit_after": vars(after),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--participants", type=int, default=100, help="simulated participants in the load run (default 100)")
    p.add_argument("--fault-participants", type=int, default=20, help="simulated participants in the SIGKILL run (default 20)")
    p.add_argument("--clients", type=int, default=2, help="client processes (default 2)")
    p.add_argument("--think", type=float, default=1.0, help="mean seconds a paced participant thinks before a pick (default 1)")
    p.add_argument("--run", default=None, help="a trained ego for the agent condition (default: the oracle agent)")
    p.add_argument("--name", default="study_server", help="result file name under benchmarks/results/")
    args = p.parse_args()
    for option, value in (("--participants", args.participants), ("--fault-participants", args.fault_participants)):
        if value < 4 or value % 4:
            p.error(f"{option} must be a positive multiple of 4 (half with the agent, half in pairs), got {value}")
    if args.clients < 1:
        p.error(f"--clients must be at least 1, got {args.clients}")
    with tempfile.TemporaryDirectory(prefix="study-bench-") as tmp:
        root = Path(tmp)
        loadavg = os.getloadavg()
        runs = [load(args.participants, args.clients, args.run, root, think) for think in (0.0, args.think)]
        faulted = faults(args.fault_participants, args.clients, args.run, root)
    print(f"{'load':<28}{'request':<10}{'n':>7}{'p50 ms':>10}{'p99 ms':>10}{'max ms':>10}")
    for loaded in runs:
        pace = "as fast as answered" if loaded["think_s"] == 0 else f"thinking ~{loaded['think_s']:g} s"
        for kind, s in loaded["latency"].items():
            print(f"{pace:<28}{kind:<10}{s['n']:>7}{s['p50_ms']:>10}{s['p99_ms']:>10}{s['max_ms']:>10}")
    for loaded in runs:
        a = loaded["audit"]
        print(
            f"load ({loaded['think_s']:g} s think): {loaded['participants']} participants ({loaded['with_agent']} with the agent, {loaded['in_human_pairs']} in human pairs), "
            f"{a['tries']} tries in {loaded['wall_s']} s ({loaded['tries_per_s']} tries/s, server CPU {loaded['server_cpu_s']} s); lost {a['lost']}, duplicated {a['duplicated']}, unfinished {a['unfinished']}"
        )
    b, c = faulted["audit_before_kill"], faulted["audit_after"]
    print(
        f"faults: {faulted['participants']} participants, SIGKILL at {faulted['tries_at_kill']} stored tries "
        f"({faulted['acknowledged_before_kill']} acknowledged), back in {faulted['outage_s']} s; "
        f"lost before the kill {b['lost']}, lost after {c['lost']}, duplicated {c['duplicated']}, unfinished {c['unfinished']}, "
        f"resumed in their session {faulted['resumed_same_session']}/{faulted['participants']}"
    )
    path = write_result(
        args.name,
        {
            "load": runs[0],
            "load_paced": runs[1],
            "faults": faulted,
            "clients": args.clients,
            "agent": args.run or "oracle",
            "loadavg_at_start": loadavg,
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
