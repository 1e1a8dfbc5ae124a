"""`RateLimit`: N requests per client in any window, with a fake clock."""

from __future__ import annotations

import pytest

from rllib_conv.play import rate_limit
from rllib_conv.play.rate_limit import RateLimit


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_n_per_window_per_client_then_the_wait_until_the_oldest_leaves() -> None:
    clock = Clock()
    limit = RateLimit(2, window_s=60, clock=clock)
    assert [limit.wait("a"), limit.wait("a")] == [0.0, 0.0]
    clock.now += 10
    assert limit.wait("a") == pytest.approx(50.0)  # the first leaves the window in 50 s
    assert limit.wait("b") == 0.0  # another client has its own count
    clock.now += 50
    assert [limit.wait("a"), limit.wait("a")] == [0.0, 0.0]  # the refused one was not counted: both places are free again
    assert limit.wait("a") == pytest.approx(60.0)


def test_zero_is_no_limit_and_negative_is_refused() -> None:
    limit = RateLimit(0)
    assert all(limit.wait("a") == 0.0 for _ in range(1000))
    with pytest.raises(ValueError, match="limit must be 0"):
        RateLimit(-1)


def test_many_clients_are_forgotten_once_idle(monkeypatch) -> None:
    monkeypatch.setattr(rate_limit, "MAX_CLIENTS", 10)
    clock = Clock()
    limit = RateLimit(1, window_s=1, clock=clock)
    for i in range(10):
        limit.wait(f"c{i}")
    clock.now += 2
    limit.wait("new")
    assert set(limit._seen) == {"new"}
