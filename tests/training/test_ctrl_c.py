"""`tuning._noticing_ctrl_c`: a Ctrl-C that Tune's handler takes is noticed, one that never came is not.

Tune's handler stops the run and puts back the handler it found, telling no one; these tests play
Tune's part with a handler that does the same, and send a real SIGINT to this process.
"""

from __future__ import annotations

import signal

import pytest

from rllib_conv.training.tuning import _noticing_ctrl_c


def _install_tune_like_handler() -> list[int]:
    """What `ray.tune.tune._setup_signal_catching` does: on SIGINT, note it and restore the handler found."""
    found, seen = signal.getsignal(signal.SIGINT), []

    def handler(signum: int, frame: object) -> None:
        seen.append(signum)
        signal.signal(signal.SIGINT, found)

    signal.signal(signal.SIGINT, handler)
    return seen


def test_a_ctrl_c_taken_by_tune_is_noticed_and_the_handler_before_is_back() -> None:
    before = signal.getsignal(signal.SIGINT)
    with _noticing_ctrl_c() as fired:
        seen = _install_tune_like_handler()
        signal.raise_signal(signal.SIGINT)
    assert seen == [signal.SIGINT] and fired == [True]
    assert signal.getsignal(signal.SIGINT) is before


def test_no_ctrl_c_is_not_noticed() -> None:
    with _noticing_ctrl_c() as fired:
        _install_tune_like_handler()  # a finished run leaves Tune's handler in place
    assert fired == [False]


def test_a_second_ctrl_c_still_raises() -> None:
    with pytest.raises(KeyboardInterrupt), _noticing_ctrl_c():
        _install_tune_like_handler()
        signal.raise_signal(signal.SIGINT)  # Tune's: graceful stop
        signal.raise_signal(signal.SIGINT)  # ours: stop now
