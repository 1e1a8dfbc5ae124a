"""`RateLimit`: at most N requests per client address in any window of W seconds (enrolment's limit).

One client enrolling participants as fast as it can would fill the study (and its balanced
assignment) with sessions nobody plays, and try ids at will; a person enrols once, a lab
behind one address a few times a minute. Only what was let through is counted, so a
client that keeps asking is let through again once its oldest request leaves the window.
"""

from __future__ import annotations

import time
from collections import deque
from typing import Callable

WINDOW_S = 60.0
MAX_CLIENTS = 10_000  # beyond this many addresses, those with nothing in the window are forgotten


class RateLimit:
    """At most `limit` requests per client in any `window_s` seconds (`limit` 0: no limit)."""

    def __init__(self, limit: int, window_s: float = WINDOW_S, clock: Callable[[], float] = time.monotonic) -> None:
        if limit < 0:
            raise ValueError(f"limit must be 0 (no limit) or more, got {limit}")
        self.limit = limit
        self.window_s = window_s
        self.clock = clock
        self._seen: dict[str, deque[float]] = {}

    def wait(self, client: str) -> float:
        """0 if `client` may make a request now (and count it), else the seconds until it may."""
        if self.limit == 0:
            return 0.0
        now = self.clock()
        times = self._seen.setdefault(client, deque())
        while times and now - times[0] >= self.window_s:
            times.popleft()
        if len(times) >= self.limit:
            return self.window_s - (now - times[0])
        times.append(now)
        if len(self._seen) > MAX_CLIENTS:
            self._forget(now)
        return 0.0

    def _forget(self, now: float) -> None:
        for client in [c for c, t in self._seen.items() if not t or now - t[-1] >= self.window_s]:
            del self._seen[client]
