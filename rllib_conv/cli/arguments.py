"""The command line's vocabulary: argument types, the options most commands share, and help texts taken from the schemas.

An option that sets a config key shows that key's description in the pipeline's schema
(`described`), and `adapt --help` / `zeroshot --help` list the keys no option sets
(`set_help`), and `partners train --help` the partner generators' keys (`keys_help`), so a
default or a meaning is written once, in the schema.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from typing import NoReturn

from pydantic import BaseModel

from rllib_conv.cli.commands import ADAPT_OPTIONS, ZEROSHOT_OPTIONS
from rllib_conv.common.tracking import DEFAULT_LOGGERS, LOGGERS
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.pair_config import MAX_EPISODES
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig

EXIT_USAGE = 2
MAX_COUNT = MAX_EPISODES  # counts (episodes, seeds, steps) beyond any real use are refused before they overflow a counter

PER_TRIAL = {"run", "partner"}  # schema keys filled in for each Tune trial, not by users


def described(schema: type[BaseModel], key: str) -> str:
    """The help text of the option that sets `key`: the schema's description, then its default when it has a plain one."""
    field = schema.model_fields[key]
    # A factory's or None's meaning is in the description; a required field has no default to show.
    if field.default_factory is not None or field.default is None or field.is_required():
        return str(field.description)
    default = str(field.default).lower() if isinstance(field.default, bool) else field.default
    return f"{field.description} (default: {default})"


def set_help(schema: type[BaseModel], options: dict[str, str]) -> str:
    """An epilog listing the `--set` keys of a command that no option sets, described by the schema."""
    keys = [k for k in schema.model_fields if k not in options and k not in PER_TRIAL]
    return keys_help(schema, keys, "--set keys besides the options:")


def keys_help(schema: type[BaseModel], keys: Sequence[str], title: str) -> str:
    """An epilog: `title`, then each of `keys` with its description in the schema."""
    described_keys = {k: described(schema, k) for k in keys}
    width = max(map(len, described_keys))
    return title + "\n" + "\n".join(f"  {k.ljust(width)}  {v}" for k, v in described_keys.items())


# The self-play keys that make a population one of the field's partner generators (`partners train --help`).
GENERATOR_KEYS = ("fcp", "population_entropy", "trajectory_diversity", "trajectory_discount", "hidden_utility")


ADAPT_SET_KEYS = {k: described(AdaptConfig, k) for k in AdaptConfig.model_fields if k not in ADAPT_OPTIONS and k not in PER_TRIAL}
ZEROSHOT_SET_KEYS = {
    k: described(ZeroShotConfig, k) for k in ZeroShotConfig.model_fields if k not in ZEROSHOT_OPTIONS and k not in PER_TRIAL
}


class Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one `rllib-conv: error:` line and exit 2, like every other bad input."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"rllib-conv: error: {self.prog}: {message} (see {self.prog} --help)\n")
        sys.exit(EXIT_USAGE)


def positive_int(text: str) -> int:
    """A count: a whole number from 1 to `MAX_COUNT` (argparse names the option when it is not)."""
    try:
        value = int(text)
    except ValueError:  # not a number, or more digits than Python converts
        value = 0
    shown = text if len(text) <= 24 else f"{text[:20]}... ({len(text)} characters)"
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {shown!r}")
    if value > MAX_COUNT:
        raise argparse.ArgumentTypeError(f"expected a whole number from 1 to {MAX_COUNT}, got {shown!r}")
    return value


def run_args(p: argparse.ArgumentParser, storage: bool = True) -> None:
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a config value, VALUE in YAML, e.g. --set lam=0.3 or --set ppo.lr=1e-4 (repeatable)",
    )
    if storage:
        p.add_argument("--storage", default="runs", help="folder for Tune's experiments and checkpoints (default: runs)")
    p.add_argument(
        "--address", default=None, help="Ray cluster address (auto or HOST:PORT); default: $RAY_ADDRESS or a local Ray"
    )


def log_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--log",
        nargs="+",
        choices=LOGGERS,
        default=list(DEFAULT_LOGGERS),
        metavar="TRACKER",
        help="experiment tracking: tensorboard (event files in every trial folder, always written), wandb (offline "
        "unless $WANDB_MODE says otherwise; files in the experiment folder's wandb/), mlflow (a local store in its mlruns/); "
        "wandb and mlflow need pip install 'rllib-conv[tracking]' (default: tensorboard)",
    )


def runs_args(p: argparse.ArgumentParser, out: str, what: str) -> None:
    """RUNS, and the name and folder of the CSV a command writes after them."""
    p.add_argument("runs", nargs="+", metavar="RUNS", help="trained-ego trial folders or experiment folders")
    p.add_argument("--name", help=f"name of the output CSV{what} (default: after RUNS and the options that differ)")
    p.add_argument("--out", default=out, help=f"folder for the CSV (default: {out})")
