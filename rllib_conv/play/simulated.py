"""Scripted participants: rehearse a study against a running server, as the load and fault checks do.

Each simulated participant does what the page does, over HTTP and a WebSocket: enrols
with its id, listens to its live view, picks a good arm (bandit) whenever the view says
it may, and stops at the completion code. When the server goes away (killed, restarted)
it retries with the same id until `deadline_s`: enrolling again resumes its session,
and a move answered with 409 (already played before the crash) is not played twice.

What it saw is kept (`Outcome`): every try shown to it as played (`seen`, the
acknowledged tries the database must hold), its completion code, and the latency of every
request by kind. Needs httpx (the test extra).
"""

from __future__ import annotations

import asyncio
import json
import random
import time
from dataclasses import dataclass, field
from typing import Any

import httpx
import websockets

RETRY_S = 0.2
DONE_PHASES = ("finished", "ended")


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
    reconnects: int = 0
    conflicts: int = 0


class Participant:
    """One scripted participant of the bandit study (module docstring)."""

    def __init__(self, client: httpx.AsyncClient, base_url: str, pid: str, seed: int = 0, deadline_s: float = 120.0) -> None:
        self.client = client
        self.base = base_url.rstrip("/")
        self.ws_url = self.base.replace("http://", "ws://", 1).replace("https://", "wss://", 1) + "/api/live?token="
        self.out = Outcome(pid)
        self.rng = random.Random(f"{seed}:{pid}")
        self.deadline = time.monotonic() + deadline_s
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
            self.out.reconnects += 1
            await asyncio.sleep(RETRY_S)

    async def _enrol(self) -> None:
        r = await self._request("enrol", "POST", "/api/participants", {"consent": True, "participant": self.out.participant})
        r.raise_for_status()
        data = r.json()
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
            self.out.reconnects += 1
            await asyncio.sleep(RETRY_S)
            await self._enrol()  # the server may have restarted: resume by id

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
                    r = await self._request("move", "POST", "/api/move", {"token": self.token, "step": self.view["step"], "arm": self._arm()})
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


async def simulate(base_url: str, ids: list[str], seed: int = 0, deadline_s: float = 120.0) -> list[Outcome]:
    """Run one simulated participant per id at once against the server at `base_url`; their outcomes, in order."""
    limits = httpx.Limits(max_connections=len(ids) + 10, max_keepalive_connections=len(ids) + 10)
    async with httpx.AsyncClient(limits=limits, timeout=httpx.Timeout(15.0)) as client:
        return list(await asyncio.gather(*(Participant(client, base_url, pid, seed, deadline_s).play() for pid in ids)))
