"""Experiment files: YAML (or a dict) with Tune grids and `--set` overrides, validated against a typed schema.

Any value may be a Tune grid, written `{grid_search: [a, b, ...]}` in YAML. Every
combination is validated before anything runs. This module holds the one validator
(`check`): every problem is one clause naming its key (`ppo.minibatch_size: Input should
be greater than 0`), blamed on what set that key: a `--set KEY=VALUE`, a command-line
option, or the file (or "arguments") otherwise. The schemas themselves live beside what
they configure: `rllib_conv.training.experiment.ExperimentConfig` (an ego), and one per
pipeline in `rllib_conv.pipelines` (adaptation, zero-shot, self-play, reproduce plans).

A config is validated once, where it enters (the CLI, `reproduce`'s plans, a test), into a
`Checked`: its raw dict (the Tune param space, grids kept) with every grid combination
validated. The pipelines take `Checked` values and do not validate again.
"""

from __future__ import annotations

import copy
import itertools
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

GRID_KEY = "grid_search"
SET = "--set"

# Parts of a pydantic error location that name a type tried, not a key: a union's members
# (`constrained-float`, `list[tuple[int, float]]`, `function-after[...]`). Users never wrote
# them, so they are dropped from the key path a message names.
_TYPE_TAG = re.compile(r"^(constrained-\w+|function-\w+\[.*\]|\w+\[.*\]|int|float|str|bool|none|list|dict|tuple|literal\[.*\])$")

# Origins: key path -> the option that set it (`("pick_steps",): "--pick-steps"`).
Origins = Mapping[tuple[str, ...], str]

S = TypeVar("S", bound=BaseModel)


class Strict(BaseModel):
    """Base of every schema: unknown keys are errors, and so are bad values set later."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True)


@dataclass(frozen=True)
class Checked(Generic[S]):
    """A config validated once, with its grids: what every pipeline takes.

    `raw` is the Tune param space (grids kept as `{grid_search: [...]}`; treat it as
    read-only), `variants` every grid combination validated against the schema, in
    `expand_grid`'s order. Built by `checked`, `with_sets` or `load_checked` only, so a
    `Checked` always passed the validator.
    """

    raw: dict[str, Any]
    variants: tuple[S, ...]

    @property
    def first(self) -> S:
        """The first grid combination (the only one of a config without grids)."""
        return self.variants[0]


def _key_path(loc: Sequence[Any]) -> tuple[str, ...]:
    """The key path of a pydantic error location, without the union members it tried."""
    return tuple(str(p) for p in loc if not (isinstance(p, str) and _TYPE_TAG.match(p)))


def _message(error: Mapping[str, Any]) -> str:
    """A pydantic problem in words: without pydantic's `Value error, ` prefix."""
    return str(error["msg"]).removeprefix("Value error, ").removeprefix("Assertion failed, ")


def _clauses(errors: Sequence[Mapping[str, Any]]) -> list[tuple[tuple[str, ...], str]]:
    """(key path, message) per problem; a union's failed members at one key become one clause (`a; or b`)."""
    merged: dict[tuple[str, ...], list[str]] = {}
    for error in errors:
        messages = merged.setdefault(_key_path(error["loc"]), [])
        if _message(error) not in messages:
            messages.append(_message(error))
    return [(path, "; or ".join(messages)) for path, messages in merged.items()]


def describe(exc: ValidationError) -> str:
    """One clause per problem: the dotted key path and what was wrong."""
    return "; ".join(f"{'.'.join(path) or '<root>'}: {msg}" for path, msg in _clauses(exc.errors()))


def is_grid(node: Any) -> bool:
    """Whether `node` is a grid value `{grid_search: [...]}`."""
    return isinstance(node, dict) and set(node) == {GRID_KEY}


class GridError(ValueError):
    """A `{grid_search: ...}` that is not a non-empty list; `path` is its key path."""

    def __init__(self, path: tuple, message: str) -> None:
        super().__init__(message)
        self.path = tuple(str(p) for p in path)


def _grid_paths(node: Any, path: tuple = ()) -> list[tuple[tuple, list]]:
    """Return (key path, values) of every `{grid_search: [...]}` in a nested dict."""
    if is_grid(node):
        values = node[GRID_KEY]
        if not isinstance(values, list) or not values:
            raise GridError(path, f"{'.'.join(map(str, path))}: grid_search needs a non-empty list, got {values!r}")
        return [(path, values)]
    if isinstance(node, dict):
        return [g for k, v in node.items() for g in _grid_paths(v, (*path, k))]
    return []


def set_path(node: dict, path: tuple, value: Any) -> None:
    """Set `node[path[0]][path[1]]... = value`, creating the dicts on the way."""
    for key in path[:-1]:
        node = node.setdefault(key, {})
    node[path[-1]] = value


def has_path(node: Any, path: Sequence[str]) -> bool:
    """Whether the nested mapping `node` has a value at `path`."""
    for key in path:
        if not isinstance(node, dict) or key not in node:
            return False
        node = node[key]
    return True


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


def _blame(path: tuple[str, ...], msg: str, origins: Origins, default: str) -> tuple[str, str]:
    """One problem as (what set its key, the clause): an option named alone says the problem alone."""
    for key, origin in origins.items():
        n = min(len(key), len(path))
        if path and path[:n] == key[:n]:
            return origin, msg if path == key and not origin.startswith(SET) else f"{'.'.join(path)}: {msg}"
    if not path and origins:  # a check across keys: the file (or arguments) together with the options given
        return f"{default} with {', '.join(dict.fromkeys(origins.values()))}", msg
    return default, f"{'.'.join(path)}: {msg}" if path else msg


def blamed(exc: ValidationError, origins: Origins, default: str) -> str:
    """Every problem of `exc`, grouped by what it is blamed on: `--set a=1: a: ...; file.yaml: b: ...; c: ...`."""
    grouped: dict[str, list[str]] = {}
    for path, msg in _clauses(exc.errors()):
        origin, clause = _blame(path, msg, origins, default)
        grouped.setdefault(origin, []).append(clause)
    return "; ".join(f"{origin}: {'; '.join(clauses)}" for origin, clauses in grouped.items())


def check(raw: Any, schema: type[BaseModel], origins: Origins | None = None, default: str = "arguments") -> list[Any]:
    """Every grid combination of `raw`, validated against `schema`: the one validator of every config.

    `origins` maps key paths to the options that set them (`--pick-steps`, `--set lam=0.3`);
    a problem at any other key is blamed on `default` (the YAML file, or "arguments"). An
    option is blamed only where it set a value: one left unset takes no blame. ValueError:
    one line naming the culprit.
    """
    if not isinstance(raw, dict):
        raise ValueError(f"{default}: expected a mapping of settings, got {type(raw).__name__}")
    try:
        combos = expand_grid(raw)
    except GridError as exc:
        blame = next((origin for key, origin in (origins or {}).items() if exc.path[: len(key)] == key), default)
        raise ValueError(f"{blame}: {exc}") from None
    variants = []
    for variant in combos:
        try:
            variants.append(schema.model_validate(variant))
        except ValidationError as exc:
            given = {key: origin for key, origin in (origins or {}).items() if has_path(variant, key)}
            raise ValueError(blamed(exc, given, default)) from None
    return variants


def checked(raw: Any, schema: type[S], source: str = "config", origins: Origins | None = None) -> Checked[S]:
    """`raw` (a copy) with every grid combination validated against `schema` (`check`; problems blamed on `origins`, else `source`)."""
    variants = check(raw, schema, origins, source)  # ValueError on a non-mapping, before the copy
    return Checked(copy.deepcopy(raw), tuple(variants))


def shown(text: str, limit: int = 80) -> str:
    """`text` as an error message repeats it: whole, or its start and its length when long."""
    return text if len(text) <= limit else f"{text[: limit - 20]}... ({len(text)} characters)"


def _first_words(exc: BaseException, limit: int = 200) -> str:
    """An exception's message on one line, cut at `limit` characters."""
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def yaml_value(text: str, what: str) -> Any:
    """`text` parsed as YAML; ValueError naming `what` when it is not valid YAML."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{what}: not valid YAML ({' '.join(str(exc).split())})") from None
    except (ValueError, RecursionError) as exc:  # a number too long for Python's int(), nesting too deep to parse
        raise ValueError(f"{what}: not a value this tool reads ({_first_words(exc)})") from None


def parse_override(text: str) -> tuple[tuple[str, ...], Any]:
    """Parse `--set key.path=value` (value in YAML syntax) into (path, value); ValueError naming the `--set`."""
    if "=" not in text:
        raise ValueError(f"{SET} expects key=value, got {shown(text)!r}")
    key, value = text.split("=", 1)
    if not key or any(not part for part in key.split(".")):
        raise ValueError(f"{SET} expects a dotted key like ppo.lr, got {shown(key)!r}")
    return tuple(key.split(".")), yaml_value(value, f"{SET} {shown(text)}")


def with_sets(
    raw: dict[str, Any], sets: Sequence[str], schema: type[S], origins: Origins | None = None, default: str = "arguments"
) -> Checked[S]:
    """`raw` with the `--set KEY=VALUE` overrides applied (a copy), checked: its grid combinations validated (`check`)."""
    if not isinstance(raw, dict):
        raise ValueError(f"{default}: expected a mapping of settings, got {type(raw).__name__}")
    raw, origins = copy.deepcopy(raw), dict(origins or {})
    for text in sets:
        key, value = parse_override(text)
        try:
            set_path(raw, key, value)
        except (AttributeError, TypeError):  # a key below a value that is not a mapping (lam.x=1)
            raise ValueError(f"{SET} {shown(text)}: {'.'.join(key[:-1])} is not a section of settings") from None
        origins[key] = f"{SET} {shown(text)}"
    return Checked(raw, tuple(check(raw, schema, origins, default)))


def validate(raw: dict[str, Any], source: str = "config", *, schema: type[BaseModel]) -> list:
    """Validate every grid combination of `raw` against `schema`; return them. ValueError names `source` and the bad key."""
    return check(raw, schema, {}, source)


def from_dict(
    raw: dict[str, Any], overrides: Sequence[str] = (), *, schema: type[BaseModel], source: str = "arguments"
) -> dict[str, Any]:
    """Apply `--set` overrides to `raw` and validate it against `schema`; return the raw dict."""
    return with_sets(raw, overrides, schema, {}, source).raw


def read_yaml(path: str | Path, what: str = "config file") -> Any:
    """The parsed YAML of `path`; ValueError naming the file when it is missing, a folder, not text or not valid YAML."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{what} {str(path)!r} is a folder; expected a YAML file")
    if not path.is_file():
        raise ValueError(f"{what} {str(path)!r} does not exist")
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{what} {str(path)!r} is not UTF-8 text (byte {exc.start}); expected a YAML file") from None
    except OSError as exc:
        raise ValueError(f"{what} {str(path)!r} cannot be read ({exc.strerror})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{what} {str(path)!r} is not valid YAML: {' '.join(str(exc).split())}") from None
    except (ValueError, RecursionError) as exc:  # a number too long for Python's int(), nesting too deep to parse
        raise ValueError(f"{what} {str(path)!r} holds what this tool cannot read: {_first_words(exc)}") from None


def load_checked(path: str | Path, overrides: Sequence[str] = (), *, schema: type[S]) -> Checked[S]:
    """A config YAML with its `--set` overrides, checked: the raw dict (grids kept, for Tune) and every combination validated.

    Problems name the `--set` that caused them, else the file.
    """
    raw = read_yaml(path)
    return with_sets({} if raw is None else raw, overrides, schema, {}, str(path))


def load(path: str | Path, overrides: Sequence[str] = (), *, schema: type[BaseModel]) -> dict[str, Any]:
    """Read a config YAML, apply `--set` overrides, validate every grid combination against `schema`.

    Returns the raw dict (grids kept as `{grid_search: [...]}`) for Tune.
    """
    return load_checked(path, overrides, schema=schema).raw
