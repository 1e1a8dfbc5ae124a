"""Scripted participants: rehearse a study against a running server, as the load and fault checks do.

`ServerProcess` runs the real `rllib-conv play` in a subprocess (to kill it with SIGKILL).

Each simulated participant does what the page does, over HTTP and a WebSocket: enrols
with its id, listens to its live view, picks a good arm (bandit) whenever the view says
it may, and stops at the completion code. When the server goes away (killed, restarted)
it retries with the same id until `deadline_s`: enrolling again with the id and the token
its first enrolment gave (as the page keeps it) resumes its session, and a move answered
with 409 (already played before the crash) is not played twice.

What it saw is kept (`Outcome`): every try shown to it as played (`seen`, the
acknowledged tries the database must hold), its completion code, and the latency of every
request by kind; `audit` checks a study database against what the participants saw.
Needs httpx (the test extra).
"""

from __future__ import annotations

import asyncio
import json
import os
import random
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Awaitable, Callable

import httpx
import websockets

from rllib_conv.play.store import Store

RETRY_S = 0.2
DONE_PHASES = ("finished", "ended")
START_S = 60.0


def _default_sigint() -> None:
    """In the child before it runs the server: SIGINT back to its default, so Python turns it into KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class ServerProcess:
    """`rllib-conv play ARGS` in a subprocess, the real command, to be stopped with Ctrl-C or SIGKILL."""

    def __init__(self, args: list[str]) -> None:
        cmd = [sys.executable, "-m", "rllib_conv.cli", "play", *args]
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        # Ctrl-C must reach it even when this process was started with SIGINT ignored (a shell's background job,
        # `nohup ... &`): an ignored SIGINT is inherited, and the server would then stop with status 0, not 130.
        self.proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, preexec_fn=_default_sigint
        )
        self.lines: list[str] = []
        self.url = ""
        deadline = time.monotonic() + START_S
        while not self.url and time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            self.lines.append(line)
            if line.startswith("open http://"):
                self.url = line.split()[1]
        if not self.url:
            self.close()
            raise RuntimeError("the study server did not start:\n" + "".join(self.lines))

    @property
    def port(self) -> int:
        """The port it listens on."""
        return int(self.url.rstrip("/").rsplit(":", 1)[1])

    def kill(self) -> None:
        """SIGKILL: no shutdown code runs."""
        self.proc.send_signal(signal.SIGKILL)
        self.proc.wait(timeout=20)

    def interrupt(self) -> int:
        """Ctrl-C; return the exit status."""
        self.proc.send_signal(signal.SIGINT)
        return self.proc.wait(timeout=20)

    def close(self) -> None:
        """Kill it if it still runs; release its pipe."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        self.proc.stdout.close()


@dataclass
class Outcome:
    """What one simulated participant saw: its tries as played (task, context, try) -> (my arm, partner's arm), code, latencies."""

    participant: str
    partner: str = "nobody"
    seen: dict[tuple[str, str, int], tuple[int, int]] = field(default_factory=dict)
    completion_code: str | None = None
    phase: str = ""
    latencies: dict[str, list[float]] = field(default_factory=dict)
    tokens: set[str] = field(default_factory=set)  # more than one: a resume did not find the session
    seen_before_outage: dict[tuple[str, str, int], tuple[int, int]] | None = None  # `seen` when the server first went away
    reconnects: int = 0
    conflicts: int = 0
    resumes: int = 0  # re-enrolments with the session's token that the server accepted
    refused_resumes: int = 0


class Participant:
    """One scripted participant of the bandit study (module docstring); it thinks 0.5-1.5 x `think_s` seconds before each pick."""

    def __init__(
        self, client: httpx.AsyncClient, base_url: str, pid: str, seed: int = 0, deadline_s: float = 120.0, think_s: float = 0.0
    ) -> None:
        self.client = client
        self.base = base_url.rstrip("/")
        self.ws_url = self.base.replace("http://", "ws://", 1).replace("https://", "wss://", 1) + "/api/live?token="
        self.out = Outcome(pid)
        self.rng = random.Random(f"{seed}:{pid}")
        self.deadline = time.monotonic() + deadline_s
        self.think_s = think_s
        self.token: str | None = None
        self.view: dict[str, Any] = {"version": -1}
        self.changed = asyncio.Event()

    def _take(self, view: dict[str, Any]) -> None:
        """Keep the newest view, and every try it shows as played."""
        for h in view.get("history") or ():
            self.out.seen[(h["task"], h["context"], h["try"])] = (h["you"], h["partner"])
        if view.get("version", -1) >= self.view.get("version", -1):
            self.view = view
            self.out.partner = view.get("partner", self.out.partner)
            self.out.phase = view.get("phase", "")
            self.out.completion_code = view.get("completion_code")
        self.changed.set()

    async def _request(self, kind: str, method: str, path: str, body: dict | None = None) -> httpx.Response:
        """One request, retried on connection errors and 503 until the deadline; its latency is kept under `kind`."""
        while True:
            start = time.perf_counter()
            try:
                r = await self.client.request(method, self.base + path, json=body)
                if r.status_code != 503:
                    self.out.latencies.setdefault(kind, []).append(time.perf_counter() - start)
                    return r
            except httpx.TransportError:
                pass
            if time.monotonic() > self.deadline:
                raise TimeoutError(f"{self.out.participant}: no answer to {method} {path} before the deadline")
            self._lost_server()
            await asyncio.sleep(RETRY_S)

    async def _enrol(self) -> None:
        body = {"consent": True, "participant": self.out.participant}
        if self.token is not None:
            body["token"] = self.token  # a resume proves it is the same participant
        r = await self._request("enrol", "POST", "/api/participants", body)
        if r.status_code != 200 and self.token is not None:
            self.out.refused_resumes += 1
        r.raise_for_status()
        data = r.json()
        self.out.resumes += self.token is not None
        self.token = data["token"]
        self.out.tokens.add(self.token)
        self._take(data["view"])

    async def _listen(self) -> None:
        """Read live views until the session is over, reopening the socket (and re-enrolling) when it drops."""
        while self.view.get("phase") not in DONE_PHASES:
            try:
                async with websockets.connect(self.ws_url + self.token, open_timeout=10) as ws:
                    async for message in ws:
                        self._take(json.loads(message))
                        if self.view.get("phase") in DONE_PHASES:
                            return
            except (OSError, websockets.WebSocketException, TimeoutError):
                pass
            if time.monotonic() > self.deadline:
                return
            self._lost_server()
            await asyncio.sleep(RETRY_S)
            await self._enrol()  # the server may have restarted: resume by id

    def _lost_server(self) -> None:
        if self.out.seen_before_outage is None:
            self.out.seen_before_outage = dict(self.out.seen)  # what was acknowledged before the outage
        self.out.reconnects += 1

    def _arm(self) -> int:
        good = [a["arm"] for a in self.view["arms"] if a["prize"] > 0]
        return self.rng.choice(good or [1])

    async def play(self) -> Outcome:
        """Play the whole session; return what was seen."""
        await self._enrol()
        listener = asyncio.ensure_future(self._listen())
        try:
            while self.view.get("phase") not in DONE_PHASES and time.monotonic() < self.deadline:
                if self.view.get("phase") == "choose":
                    if self.think_s > 0:
                        await asyncio.sleep(self.rng.uniform(0.5, 1.5) * self.think_s)
                    r = await self._request(
                        "move", "POST", "/api/move", {"token": self.token, "step": self.view["step"], "arm": self._arm()}
                    )
                    if r.status_code == 200:
                        self._take(r.json())
                        continue
                    if r.status_code != 409:  # 409: played already (an answer lost in a crash) or stale
                        r.raise_for_status()
                    self.out.conflicts += 1
                    self._take((await self._request("session", "GET", f"/api/session?token={self.token}")).json())
                    continue
                self.changed.clear()
                try:
                    await asyncio.wait_for(self.changed.wait(), timeout=2.0)
                except TimeoutError:
                    if listener.done():  # the socket gave up: ask directly
                        self._take((await self._request("session", "GET", f"/api/session?token={self.token}")).json())
        finally:
            listener.cancel()
        return self.out


async def simulate(
    base_url: str,
    ids: list[str],
    seed: int = 0,
    deadline_s: float = 120.0,
    think_s: float = 0.0,
    during: Callable[[], Awaitable[Any]] | None = None,
) -> list[Outcome]:
    """Run one simulated participant per id at once against the server at `base_url`; their outcomes, in order.

    `think_s`: each participant's mean pause before a pick (0: as fast as the server
    answers); `during()` runs beside them (e.g. kills and restarts the server).
    """
    limits = httpx.Limits(max_connections=len(ids) + 10, max_keepalive_connections=len(ids) + 10)
    async with httpx.AsyncClient(limits=limits, timeout=httpx.Timeout(15.0)) as client:
        plays = [asyncio.ensure_future(Participant(client, base_url, pid, seed, deadline_s, think_s).play()) for pid in ids]
        if during is not None:
            await during()
        return list(await asyncio.gather(*plays))


@dataclass
class Audit:
    """What the database holds against what the simulated participants were shown.

    `lost`: tries a participant was shown as played that the database lacks, or holds with
    other arms; `duplicated`: tries stored twice for one (pair, task, context, try), or
    beyond a session's length; `unfinished`: participants without a completion code;
    `new_tokens`: participants whose resume found another session than their first.
    """

    participants: int
    finished: int
    pairs: int
    tries: int
    lost: int
    duplicated: int
    unfinished: int
    new_tokens: int


def audit(db: str | Path, outcomes: list[Outcome], before_outage: bool = False, session_tries: int = 30) -> Audit:
    """Check the study database `db` against what `outcomes` saw (`before_outage`: what they saw before the server went away)."""
    store = Store(db, readonly=True)
    try:
        seats = {p.id: (p.pair, p.seat) for p in store.participants()}
        rows: dict[int, dict[tuple, tuple[int, int]]] = {}
        duplicated = 0
        for r in store.tries():
            key = (r["task"], r["context"], r["try"])
            duplicated += key in rows.setdefault(r["pair"], {})
            rows[r["pair"]][key] = (r["action_1"], r["action_2"])
    finally:
        store.close()
    duplicated += sum(max(0, len(tries) - session_tries) for tries in rows.values())
    lost = 0
    for o in outcomes:
        pair, seat = seats.get(o.participant, (None, None))
        shown = o.seen_before_outage if before_outage and o.seen_before_outage is not None else o.seen
        for key, (you, partner) in shown.items():
            stored = rows.get(pair, {}).get(key)
            lost += stored is None or (you, partner) != (stored if seat == 1 else stored[::-1])
    finished = sum(o.phase == "finished" and o.completion_code is not None for o in outcomes)
    return Audit(
        participants=len(outcomes),
        finished=finished,
        pairs=len(rows),
        tries=sum(len(t) for t in rows.values()),
        lost=lost,
        duplicated=duplicated,
        unfinished=len(outcomes) - finished,
        new_tokens=sum(len(o.tokens) > 1 for o in outcomes),
    )
