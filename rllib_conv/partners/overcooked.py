"""Overcooked's built-in populations: Carroll et al.'s human proxies, trained on this machine from the 2019 human data.

`overcooked-<layout>-bc` (behaviour cloning on upstream's train split: the partner PPO_BC
trains with, its members in the `train` split) and `overcooked-<layout>-hproxy` (the same on
the test split, other people: the held-out "human proxy", its members in the `test` split),
one member per training seed (`seed0`, `seed1`, ...), each a `trained_policy` that samples
its actions, as Carroll et al.'s proxies do.

The human data may not be redistributed, so neither are these models: `rllib-conv
human-proxies overcooked --layouts <layout>` trains them into the user's cache folder
(`<cache>/proxies/<layout>/{bc,hproxy}/population.json`, the cache of
`envs.overcooked.human_data.cache_folder`), and the names resolve to the manifests there.
Before that, `partners.names()` (`rllib-conv partners list`) does not list them, and a name
says which command to run.
"""

from __future__ import annotations

import os
from functools import partial
from pathlib import Path

from rllib_conv.common.run_folders import POPULATION_FILE
from rllib_conv.envs.overcooked.human_data import LAYOUTS, cache_folder
from rllib_conv.partners.population import Population, register_builtin

PROXY_KINDS = {"bc": "train", "hproxy": "test"}  # population kind -> the human data split it is cloned from
PROXIES_DIR = "proxies"


def population_name(layout: str, kind: str) -> str:
    """The built-in name of a layout's proxies: `overcooked-<layout>-<kind>` (`kind`: bc or hproxy)."""
    return f"overcooked-{layout}-{kind}"


def proxies_folder(layout: str, kind: str, cache: str | os.PathLike[str] | None = None) -> Path:
    """Where a layout's proxies of `kind` live: `<cache>/proxies/<layout>/<kind>` (one `seed<s>/` checkpoint per seed)."""
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)} (the layouts with human data), not {layout!r}")
    if kind not in PROXY_KINDS:
        raise ValueError(f"proxy kind must be one of {', '.join(PROXY_KINDS)}, not {kind!r}")
    return cache_folder(cache) / PROXIES_DIR / layout / kind


def proxy_population(layout: str, kind: str, cache: str | os.PathLike[str] | None = None) -> Population:
    """The trained proxies of `layout` and `kind` from the cache; ValueError naming the command that trains them."""
    manifest = proxies_folder(layout, kind, cache) / POPULATION_FILE
    if not manifest.is_file():
        raise ValueError(
            f"population {population_name(layout, kind)!r}: no trained human proxies at {str(manifest)!r}; "
            f"run `rllib-conv human-proxies overcooked --layouts {layout}` first"
        )
    return Population.load(manifest)


def trained(layout: str, kind: str, cache: str | os.PathLike[str] | None = None) -> bool:
    """Whether the proxies of `layout` and `kind` are in the cache (`partners.names()` lists only those)."""
    return (proxies_folder(layout, kind, cache) / POPULATION_FILE).is_file()


for _layout in LAYOUTS:
    for _kind in PROXY_KINDS:
        register_builtin(
            population_name(_layout, _kind), partial(proxy_population, _layout, _kind), ready=partial(trained, _layout, _kind)
        )
