"""Registry of `Partner` kinds, so population manifests can name and rebuild partners.

A kind outside the package (a test's or a user's game) is named by import path,
`kind = "package.module:Class"`: every process, Ray workers included, imports it on first
use, as `envs.registry` does for games.
"""

from __future__ import annotations

import importlib
from typing import Any

from rllib_conv.partners.base import Partner

_KINDS: dict[str, type[Partner]] = {}
# Built-in kinds imported on first use, like a user's kind: loading a trained policy needs torch
# and RLlib, which commands that only check a population's name should not wait for (~2 s).
_ON_FIRST_USE = {"trained_policy": "rllib_conv.partners.trained:TrainedPolicyPartner"}


def register_kind(cls: type[Partner]) -> type[Partner]:
    """Class decorator: make `cls` loadable from manifests under `cls.kind`."""
    if not cls.kind:
        raise ValueError(f"{cls.__name__} must set a non-empty `kind` to be registered")
    if _KINDS.get(cls.kind, cls) is not cls:
        raise ValueError(f"partner kind {cls.kind!r} is already registered by {_KINDS[cls.kind].__name__}")
    _KINDS[cls.kind] = cls
    return cls


def kinds() -> list[str]:
    """Return the registered partner kinds, sorted."""
    return sorted({*_KINDS, *_ON_FIRST_USE})


def kind_class(kind: str) -> type[Partner]:
    """The `Partner` class registered as `kind`, importing `"package.module:Class"` kinds; ValueError if there is none."""
    if kind not in _KINDS and (":" in kind or kind in _ON_FIRST_USE):
        module, _, attr = _ON_FIRST_USE.get(kind, kind).partition(":")
        try:
            found = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError, ValueError) as exc:
            raise ValueError(f"partner kind {kind!r}: cannot import {attr!r} from module {module!r} ({exc})") from None
        if not (isinstance(found, type) and issubclass(found, Partner) and found.kind == kind):
            raise ValueError(f"partner kind {kind!r}: {attr!r} is not a Partner class whose `kind` is {kind!r}")
        _KINDS.setdefault(kind, found)  # its module's `@register_kind` may have run already
    try:
        return _KINDS[kind]
    except KeyError:
        raise ValueError(
            f"unknown partner kind {kind!r}; known kinds: {', '.join(kinds())} (or give 'package.module:Class')"
        ) from None


def gives_action_probs(kind: str) -> bool:
    """Whether partners of `kind` say what their actions are drawn from (`Partner.action_probs`); False for unknown kinds."""
    try:
        cls = kind_class(kind)
    except ValueError:
        return False
    return cls.deterministic or cls.action_probs is not Partner.action_probs


def partner_from_spec(spec: dict[str, Any]) -> Partner:
    """Rebuild a partner from its manifest entry `{"name", "kind", "params"}`."""
    for key in ("name", "kind"):
        if key not in spec:
            raise ValueError(f"partner spec is missing {key!r}: {spec!r}")
    cls = kind_class(spec["kind"])
    return cls(name=spec["name"], **spec.get("params", {}))
