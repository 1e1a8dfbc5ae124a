"""`PairConfig`: the schema of `rllib-conv pair` (fixed players, one per seat, for N episodes), and how a seat splits.

Kept free of torch and Ray, so the command line checks a pairing before it loads anything;
the seat syntax (`SEAT_SYNTAX`) is what `rllib-conv pair --help` shows.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field, PositiveInt, field_validator

from rllib_conv import partners
from rllib_conv.common.config_files import Strict
from rllib_conv.common.run_folders import POPULATION_FILE
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.settings import EnvName

SEAT_SEPARATOR = ":"
MAX_EPISODES = 10**9  # beyond any real use, and within what Python's iterators and NumPy's arrays count

SEAT_SYNTAX = """\
A seat is SOURCE:WHAT, read in this order:
  KIND:PARAMS   a scripted partner kind with its parameters as a YAML mapping,
                e.g. 'bandit_convention:{arms: [0, 5, 2, 3]}' (kinds and parameters: docs/cli.md)
  RUN:MODULE    a module of a trained ego's last checkpoint: RUN:ego@NAME (the head trained with
                partner NAME), RUN:ego (the one head of agg/maml egos), RUN:task (the task module alone)
  POP:NAME      member NAME of population POP (a built-in name, a manifest or a population folder)
SOURCE is the longest part before a colon that is an existing file or folder (so a run path may
hold colons), else the part before the first colon. Seats fill the game's agents in order
(player_0, player_1, ...).
"""


def _exists(path: str) -> bool:
    """Whether `path` names a file or folder (a name no file system accepts names none)."""
    try:
        return Path(path).exists()
    except (OSError, ValueError):  # too long, or a NUL byte
        return False


def split_seat(text: str) -> tuple[str, str]:
    """Split a seat `SOURCE:WHAT`; ValueError naming the seat when it has no SOURCE or no colon.

    SOURCE is the longest part before a colon that is an existing file or folder (a run or
    manifest path may hold colons: `runs/a:b/trial:ego`); otherwise the part before the first
    colon (kind and built-in population names hold none, and a kind's PARAMS may: `{arms: [0]}`).
    """
    cuts = [i for i, c in enumerate(text) if c == SEAT_SEPARATOR]
    on_disk = [i for i in cuts if i > 0 and _exists(text[:i])]
    cut = on_disk[-1] if on_disk else cuts[0] if cuts else -1
    if cut <= 0:
        raise ValueError(f"seat {text!r}: expected SOURCE:WHAT (KIND:PARAMS, RUN:MODULE or POP:NAME)")
    return text[:cut], text[cut + 1 :]


def is_run(source: str) -> bool:
    """Whether a seat's SOURCE is a trained ego's folder (a folder that is not a population's)."""
    return Path(source).is_dir() and not (Path(source) / POPULATION_FILE).is_file()


class PairConfig(Strict):
    """Fixed players, one per seat of a game, for `episodes` episodes seeded from `seed`.

    The game is the one the seats name (a trained ego's, a population's); `env` and
    `env_config` choose it when the seats name none (scripted kinds only) or different ones.
    """

    seats: list[str] = Field(min_length=2, description="one player per seat of the game, in the game's agent order")
    episodes: PositiveInt = Field(200, le=MAX_EPISODES, description="episodes to play")
    seed: int = Field(0, description="seed of the episodes and the players")
    env: EnvName | None = Field(None, description="the game, when no seat names one or the seats name different ones")
    env_config: dict[str, Any] | None = Field(
        None, description="the game's settings as a YAML mapping, e.g. '{symmetric: 1}' (default: the seats')"
    )

    @field_validator("seats")
    @classmethod
    def _seat_syntax(cls, seats: list[str]) -> list[str]:
        for seat in seats:
            split_seat(seat)
        return seats


def population_seat(text: str) -> tuple[partners.Population, partners.PartnerEntry]:
    """The population and member the seat `text` (`POPULATION:MEMBER`) names; ValueError naming the seat.

    Checked without torch or Ray (the CLI calls it before loading them), so a misspelt seat fails in a second.
    """
    source, what = split_seat(text)
    try:
        pop = partners.get(source)
    except ValueError as exc:
        if partners.is_builtin(source):  # a built-in that needs a step first (trained human proxies) says which
            raise ValueError(f"seat {text!r}: {exc}") from None
        raise ValueError(
            f"seat {text!r}: {source!r} is neither a partner kind ({', '.join(partners.kinds())}), "
            "a trained-ego trial folder, nor a population (built-in name or manifest)"
        ) from None
    entry = next((e for e in pop.partners if e.name == what), None)
    if entry is None:
        raise ValueError(
            f"seat {text!r}: population {pop.name!r} has no member {what!r}; it has {[e.name for e in pop.partners]}"
        )
    return pop, entry


def trained_game(exp: ExperimentConfig) -> tuple[str, dict[str, Any], str]:
    """The game a trained ego played: its env, its settings (the population's, then the experiment's) and its partner's seat."""
    pop = partners.get(exp.population)
    return exp.env or pop.env, {**pop.env_config, **exp.env_config}, pop.partner_agent
