"""Name -> factory registry for the PettingZoo games configs and the CLI accept."""

from __future__ import annotations

import importlib
import inspect
from typing import Any, Callable

from pettingzoo.utils.env import AECEnv, ParallelEnv

EnvFactory = Callable[..., AECEnv | ParallelEnv]

_FACTORIES: dict[str, EnvFactory] = {}


def register(name: str, factory: EnvFactory, *, overwrite: bool = False) -> None:
    """Register `factory(**config) -> PettingZoo env` under `name`.

    Registered names are accepted by `make`, by experiment configs and by the CLI.
    Re-registering an existing name raises unless `overwrite=True`.
    """
    if not isinstance(name, str) or not name:
        raise ValueError(f"env name must be a non-empty string, got {name!r}")
    if not callable(factory):
        raise ValueError(f"factory for env {name!r} must be callable, got {factory!r}")
    if name in _FACTORIES and not overwrite:
        raise ValueError(f"env {name!r} is already registered; pass overwrite=True to replace it")
    _FACTORIES[name] = factory


def names() -> list[str]:
    """Return the registered env names, sorted."""
    return sorted(_FACTORIES)


def factory(name: str) -> EnvFactory:
    """Return the factory registered as `name`; ValueError (listing the known names) if none.

    A name `"package.module:callable"` is imported (and registered) on first use. Unlike
    `register`, which holds only in the calling process, such a name works in every Ray
    worker too (Tune trials, env runners), as long as the module is importable there.
    """
    if name in _FACTORIES:
        return _FACTORIES[name]
    if isinstance(name, str) and ":" in name:
        module, _, attr = name.partition(":")
        try:
            build = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError, ValueError) as exc:
            raise ValueError(f"env {name!r}: cannot import {attr!r} from module {module!r} ({exc})") from None
        register(name, build)
        return build
    raise ValueError(f"unknown env {name!r}; registered envs: {', '.join(names())} (or give 'package.module:callable')")


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
