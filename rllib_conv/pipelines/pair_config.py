"""`PairConfig`: the schema of `rllib-conv pair` (fixed players, one per seat, for N episodes), and how a seat splits.

Kept free of torch and Ray, so the command line checks a pairing before it loads anything;
the seat syntax is documented in `rllib-conv pair --help` (`rllib_conv.cli.SEAT_SYNTAX`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field, PositiveInt, field_validator

from rllib_conv.common.config_files import Strict
from rllib_conv.common.run_folders import POPULATION_FILE
from rllib_conv.training.settings import EnvName

SEAT_SEPARATOR = ":"


def split_seat(text: str) -> tuple[str, str]:
    """Split a seat `SOURCE:WHAT` at its first colon; ValueError naming the seat when there is none."""
    source, sep, what = text.partition(SEAT_SEPARATOR)
    if not sep or not source:
        raise ValueError(f"seat {text!r}: expected SOURCE:WHAT (KIND:PARAMS, RUN:MODULE or POP:NAME)")
    return source, what


def is_run(source: str) -> bool:
    """Whether a seat's SOURCE is a trained ego's folder (a folder that is not a population's)."""
    return Path(source).is_dir() and not (Path(source) / POPULATION_FILE).is_file()


class PairConfig(Strict):
    """Fixed players, one per seat of a game, for `episodes` episodes seeded from `seed`.

    The game is the one the seats name (a trained ego's, a population's); `env` and
    `env_config` choose it when the seats name none (scripted kinds only) or different ones.
    """

    seats: list[str] = Field(min_length=2)
    episodes: PositiveInt = 200
    seed: int = 0
    env: EnvName | None = None
    env_config: dict[str, Any] | None = None

    @field_validator("seats")
    @classmethod
    def _seat_syntax(cls, seats: list[str]) -> list[str]:
        for seat in seats:
            split_seat(seat)
        return seats
