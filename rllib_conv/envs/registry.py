"""Name -> `GameRecord` registry: the games that configs, populations and the CLI accept.

`register_game(record)` adds a game; `game(name)` is its record, which every layer asks
instead of branching on a name. `register(name, factory)` is the short form for a bare
PettingZoo env (a record with nothing but its env). A name `"package.module:attr"` is
imported on first use, in whatever process asks (Ray workers included): `attr` is a
`GameRecord` or an env factory.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
from typing import Any

from pettingzoo.utils.env import AECEnv, ParallelEnv

from rllib_conv.envs.game import EnvFactory, GameRecord

_GAMES: dict[str, GameRecord] = {}
_BUILTIN: set[str] = set()  # registered whenever `rllib_conv.envs` is imported
_MISSING: dict[str, str] = {}  # built-in games whose optional extra is not installed -> how to install it


def register_game(record: GameRecord, *, overwrite: bool = False, builtin: bool = False) -> GameRecord:
    """Register `record` under `record.name`; re-registering a name raises unless `overwrite=True`. Returns the record.

    `builtin` marks the package's own games, registered whenever `rllib_conv.envs` is imported.
    """
    if not isinstance(record, GameRecord):
        raise ValueError(f"register_game expects a GameRecord, got {record!r}")
    if record.name in _GAMES and not overwrite and _GAMES[record.name] is not record:
        raise ValueError(f"game {record.name!r} is already registered; pass overwrite=True to replace it")
    _GAMES[record.name] = record
    if builtin:
        _BUILTIN.add(record.name)
    return record


def register_missing(name: str, install: str) -> None:
    """Mark built-in game `name` as needing an optional extra that is not installed: `game(name)` says `install`."""
    _MISSING[name] = install


def found_by_name(name: str) -> bool:
    """Whether every process (a Ray worker's too) finds game `name` by its name alone: a built-in or an import path.

    Any other game was registered in this process only: its factory must travel with the config.
    """
    return name in _BUILTIN or ":" in name


def register(name: str, factory: EnvFactory, *, overwrite: bool = False) -> None:
    """Register `factory(**config) -> PettingZoo env` under `name`: a game with no oracle, key, best response or defaults.

    Registered names are accepted by `make`, by experiment configs and by the CLI.
    Re-registering an existing name raises unless `overwrite=True`.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"env name must be a non-empty string, got {name!r}")
    if not callable(factory):
        raise ValueError(f"factory for env {name!r} must be callable, got {factory!r}")
    register_game(GameRecord(name=name, env=factory), overwrite=overwrite)


def names() -> list[str]:
    """Return the registered game names, sorted."""
    return sorted(_GAMES)


def games() -> list[GameRecord]:
    """The registered games' records, by name."""
    return [_GAMES[n] for n in names()]


def game(name: str) -> GameRecord:
    """The record of game `name`; ValueError (listing the known names) if there is none.

    A name `"package.module:attr"` is imported (and registered under that name) on first use.
    Unlike `register`, which holds only in the calling process, such a name works in every
    Ray worker too (Tune trials, env runners), as long as the module is importable there.
    """
    if name in _GAMES:
        return _GAMES[name]
    if isinstance(name, str) and ":" in name:
        module, _, attr = name.partition(":")
        try:
            found = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError, ValueError) as exc:
            raise ValueError(f"env {name!r}: cannot import {attr!r} from module {module!r} ({exc})") from None
        if isinstance(found, GameRecord):
            # Runs, populations and plans name the game by this path: the record answers to it.
            return register_game(dataclasses.replace(found, name=name))
        register(name, found)
        return _GAMES[name]
    if name in _MISSING:
        raise ValueError(f"env {name!r} needs its optional extra, which is not installed: {_MISSING[name]}")
    raise ValueError(f"unknown env {name!r}; registered envs: {', '.join(names())} (or give 'package.module:callable')")


def factory(name: str) -> EnvFactory:
    """Return the env factory of game `name` (see `game`)."""
    return game(name).env


def make(name: str, **config: Any) -> AECEnv | ParallelEnv:
    """Build the registered PettingZoo env `name` with keyword `config`.

    Raises ValueError for an unknown name (listing the known ones) and whatever
    the env raises for a bad config (a ValueError naming the argument).
    """
    build = factory(name)
    accepted = _accepted_keys(build)
    unknown = sorted(set(config) - accepted) if accepted is not None else []
    if unknown:
        raise ValueError(f"env {name!r} got unknown config key(s) {unknown}; accepted: {', '.join(sorted(accepted))}")
    return build(**config)


def make_scored(name: str, **config: Any) -> AECEnv | ParallelEnv:
    """Build env `name` as every score is measured: `config` with its record's `scoring` settings over it (`GameRecord.scoring`)."""
    return make(name, **{**config, **game(name).scoring})


def _accepted_keys(build: EnvFactory) -> set[str] | None:
    """The keyword names `build` accepts, or None if it takes **kwargs (or cannot be inspected).

    A factory that reads its settings as **config declares them in `config_keys`.
    """
    declared = getattr(build, "config_keys", None)
    if declared is not None:
        return set(declared)
    target = build.__init__ if isinstance(build, type) else build
    try:
        params = inspect.signature(target).parameters.values()
    except (TypeError, ValueError):
        return None
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params):
        return None
    return {p.name for p in params if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and p.name != "self"}
