"""Registry of `Partner` kinds, so population manifests can name and rebuild partners."""

from __future__ import annotations

from typing import Any

from rllib_conv.partners.base import Partner

_KINDS: dict[str, type[Partner]] = {}


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
    return sorted(_KINDS)


def gives_action_probs(kind: str) -> bool:
    """Whether partners of `kind` say what their actions are drawn from (`Partner.action_probs`); False for unknown kinds."""
    cls = _KINDS.get(kind)
    return cls is not None and (cls.deterministic or cls.action_probs is not Partner.action_probs)


def partner_from_spec(spec: dict[str, Any]) -> Partner:
    """Rebuild a partner from its manifest entry `{"name", "kind", "params"}`."""
    for key in ("name", "kind"):
        if key not in spec:
            raise ValueError(f"partner spec is missing {key!r}: {spec!r}")
    try:
        cls = _KINDS[spec["kind"]]
    except KeyError:
        raise ValueError(f"unknown partner kind {spec['kind']!r}; known kinds: {', '.join(kinds())}") from None
    return cls(name=spec["name"], **spec.get("params", {}))
