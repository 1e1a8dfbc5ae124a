"""Where a trial's wall time goes (set-up, RLlib iterations, evaluations), reported with its results.

Every trainable of a stage adds `time/<kind>` (cumulative seconds) to each result, so the
stage benchmarks can say what the time was spent on: `setup` (building the algorithm,
loading weights), `iterate` (RLlib's `train()`: sampling and learning) and `evaluate`
(scoring egos, picking heads, exporting). What a stage's wall time times its cores leaves
beyond their sum is Tune's own overhead and idle cores.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager

TIME_PREFIX = "time/"


class Timings:
    """Cumulative wall seconds by kind; `measure(kind)` times a block."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)

    @contextmanager
    def measure(self, kind: str) -> Iterator[None]:
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[kind] += time.perf_counter() - start

    def metrics(self) -> dict[str, float]:
        """The seconds so far as result keys `time/<kind>`."""
        return {f"{TIME_PREFIX}{kind}": seconds for kind, seconds in self.seconds.items()}

    def state(self) -> dict[str, float]:
        """What a checkpoint keeps (a resumed trial goes on counting)."""
        return dict(self.seconds)

    def load(self, state: dict[str, float]) -> None:
        self.seconds.update(state)
