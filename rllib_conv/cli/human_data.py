"""The `human-data` and `human-proxies` commands' arguments: recorded human play and the proxies cloned from it.

Apart from the parser in `__init__` because they belong to one game's optional extra (`overcooked`).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

from rllib_conv.cli import commands


def human_data_parsers(command: Callable[..., argparse.ArgumentParser]) -> None:
    """Add `human-data` and `human-proxies` through the parser's `command` (name, summary, function, description)."""
    _human_data(command)
    _human_proxies(command)


def _human_data(command: Callable[..., argparse.ArgumentParser]) -> None:
    p = command(
        "human-data",
        "fetch recorded human play (Overcooked 2019) into a user cache, convert it into trajectories, summarise it",
        commands.human_data,
        description="Download the 2019 human-human Overcooked trials (in the overcooked-ai==1.1.0 sdist, through pip) into a "
        "cache folder outside the repository, convert them into one parquet file per layout and split "
        "(CACHE/trajectories/LAYOUT/{train,test}.parquet) and print trials, steps and the fraction of 'stay' per seat. "
        "Rerunning reuses what is there. The data may not be redistributed: keep it in the cache.",
    )
    p.add_argument("game", choices=["overcooked"], help="the game whose human data to fetch (overcooked)")
    p.add_argument(
        "--cache",
        default=None,
        metavar="DIR",
        help="folder for the data (default: $RLLIB_CONV_CACHE/overcooked, else ~/.cache/rllib-conv/overcooked)",
    )
    p.add_argument(
        "--layouts",
        nargs="+",
        default=None,
        metavar="LAYOUT",
        help="only these layouts (default: all five: cramped_room asymmetric_advantages coordination_ring "
        "forced_coordination counter_circuit_o_1order)",
    )


def _human_proxies(command: Callable[..., argparse.ArgumentParser]) -> None:
    p = command(
        "human-proxies",
        "train Overcooked human proxies (BC on the human train split, H_proxy on the test split) into the cache",
        commands.human_proxies,
        description="Behaviour cloning on the 2019 human trials (fetched and converted first if needed), as in Carroll et al. "
        "2019: per layout and seed, BC from upstream's train split and H_proxy from its test split, saved as the built-in "
        "populations overcooked-LAYOUT-bc and overcooked-LAYOUT-hproxy (members seed0, seed1, ...) in the cache, never "
        "in the repository. Prints each proxy's action-prediction accuracy and the returns of BC+H_proxy and BC+BC pairs.",
    )
    p.add_argument("game", choices=["overcooked"], help="the game whose human proxies to train (overcooked)")
    p.add_argument("--layouts", nargs="+", required=True, metavar="LAYOUT", help="the layouts to train proxies on")
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], metavar="SEED", help="one proxy of each kind per seed")
    p.add_argument("--episodes", type=int, default=10, help="episodes per evaluated pair (even: each seat order plays half)")
    p.add_argument(
        "--cache",
        default=None,
        metavar="DIR",
        help="the Overcooked cache folder (default: $RLLIB_CONV_CACHE/overcooked, else ~/.cache/rllib-conv/overcooked); "
        "the built-in population names read the default one",
    )
