"""Experiment files: YAML (or a dict) with Tune grids and `--set` overrides, validated against a typed schema.

Any value may be a Tune grid, written `{grid_search: [a, b, ...]}` in YAML. Every
combination is validated before anything runs; errors name the key path
(`ppo.minibatch_size: Input should be greater than 0`). The schemas themselves live beside
what they configure: `rllib_conv.training.experiment.ExperimentConfig` (an ego), and one
per pipeline in `rllib_conv.pipelines` (adaptation, zero-shot, self-play, reproduce plans).
"""

from __future__ import annotations

import copy
import itertools
from pathlib import Path
from typing import Any

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

GRID_KEY = "grid_search"


class Strict(BaseModel):
    """Base of every schema: unknown keys are errors, and so are bad values set later."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)


def describe(exc: ValidationError) -> str:
    """One clause per problem: the dotted key path and what was wrong."""
    return "; ".join(f"{'.'.join(str(p) for p in e['loc']) or '<root>'}: {e['msg']}" for e in exc.errors())


def is_grid(node: Any) -> bool:
    """Whether `node` is a grid value `{grid_search: [...]}`."""
    return isinstance(node, dict) and set(node) == {GRID_KEY}


def _grid_paths(node: Any, path: tuple = ()) -> list[tuple[tuple, list]]:
    """Return (key path, values) of every `{grid_search: [...]}` in a nested dict."""
    if is_grid(node):
        values = node[GRID_KEY]
        if not isinstance(values, list) or not values:
            raise ValueError(f"{'.'.join(map(str, path))}: grid_search needs a non-empty list, got {values!r}")
        return [(path, values)]
    if isinstance(node, dict):
        return [g for k, v in node.items() for g in _grid_paths(v, (*path, k))]
    return []


def set_path(node: dict, path: tuple, value: Any) -> None:
    """Set `node[path[0]][path[1]]... = value`, creating the dicts on the way."""
    for key in path[:-1]:
        node = node.setdefault(key, {})
    node[path[-1]] = value


def expand_grid(raw: dict[str, Any]) -> list[dict[str, Any]]:
    """Return every combination of the grid values in `raw` (one dict if there is no grid)."""
    grids = _grid_paths(raw)
    variants = []
    for combo in itertools.product(*(values for _, values in grids)):
        variant = copy.deepcopy(raw)
        for (path, _), value in zip(grids, combo):
            set_path(variant, path, value)
        variants.append(variant)
    return variants


def validate(raw: dict[str, Any], source: str = "config", *, schema: type[BaseModel]) -> list:
    """Validate every grid combination of `raw` against `schema`; return them. ValueError names the bad key."""
    if not isinstance(raw, dict):
        raise ValueError(f"{source}: expected a mapping of settings, got {type(raw).__name__}")
    out = []
    for variant in expand_grid(raw):
        try:
            out.append(schema.model_validate(variant))
        except ValidationError as exc:
            raise ValueError(f"{source}: {describe(exc)}") from None
    return out


def parse_override(text: str) -> tuple[tuple[str, ...], Any]:
    """Parse `--set key.path=value` (value in YAML syntax) into (path, value)."""
    if "=" not in text:
        raise ValueError(f"--set expects key=value, got {text!r}")
    key, value = text.split("=", 1)
    if not key or any(not part for part in key.split(".")):
        raise ValueError(f"--set expects a dotted key like ppo.lr, got {key!r}")
    return tuple(key.split(".")), yaml.safe_load(value)


def from_dict(raw: dict[str, Any], overrides: list[str] = (), *, schema: type[BaseModel], source: str = "arguments") -> dict[str, Any]:
    """Apply `--set` overrides to `raw` and validate it against `schema`; return the raw dict."""
    raw = copy.deepcopy(raw)
    for text in overrides:
        key, value = parse_override(text)
        set_path(raw, key, value)
    validate(raw, source=source, schema=schema)
    return raw


def read_yaml(path: str | Path, what: str = "config file") -> Any:
    """The parsed YAML of `path`; ValueError naming the file when it is missing or not valid YAML."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r} does not exist")
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"{what} {str(path)!r} is not valid YAML: {exc}") from None


def load(path: str | Path, overrides: list[str] = (), *, schema: type[BaseModel]) -> dict[str, Any]:
    """Read a config YAML, apply `--set` overrides, validate every grid combination against `schema`.

    Returns the raw dict (grids kept as `{grid_search: [...]}`) for Tune.
    """
    return from_dict(read_yaml(path) or {}, overrides, schema=schema, source=str(path))
