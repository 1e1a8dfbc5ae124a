"""Partner populations: named sets of fixed partners with a train/test split.

A population is stored as a small JSON manifest (YAML is read too):

    {"name": "bandit-s2-hand", "env": "bandit", "env_config": {"symmetric": 2},
     "partner_agent": "player_1", "description": "...",
     "partners": [{"name": "hand-train-0", "kind": "bandit_convention",
                   "params": {"arms": [0, 1, 2, 3]}, "split": "train",
                   "checkpoint": null, "seed": null, "score": null}, ...]}

`checkpoint`, `seed` and `score` are filled in for partners trained by self-play, and
`counterpart` holds the spec of the other seat of the pair (for cross-play). Relative
checkpoint paths are relative to the manifest's folder, so a population folder can move.
Built-in populations are addressable by name (`names()`); `get(name_or_path)` also
loads a manifest from disk.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any, Callable, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_serializer

from rllib_conv.common.atomic_files import write_text_atomically
from rllib_conv.common.config_files import GRID_KEY, describe, is_grid
from rllib_conv.common.file_versions import FileVersion, read_once
from rllib_conv.common.run_folders import POPULATION_FILE
from rllib_conv.envs.registry import factory as env_factory
from rllib_conv.partners.base import Partner
from rllib_conv.partners.kinds import partner_from_spec

Split = Literal["train", "test"]


TEAM_SEPARATOR = "+"  # games of more than two seats: the partners `a` and `b` of one episode are the team `a+b`


def teams_of(entries: list[PartnerEntry], seats: int) -> list[tuple[PartnerEntry, ...]]:
    """Every team of `entries` for `seats` partner seats, in seat order (one seat: each entry alone)."""
    return list(itertools.product(entries, repeat=seats))


def team_name(partner_names: list[str] | tuple[str, ...]) -> str:
    """The name of the partners of one episode, one per partner seat in seat order (`a+b`); one partner is its own name."""
    return TEAM_SEPARATOR.join(partner_names)


class PartnerEntry(BaseModel):
    """One partner of a population: how to rebuild it, its split, and its provenance."""

    model_config = ConfigDict(extra="forbid")

    name: str
    kind: str
    params: dict[str, Any] = Field(default_factory=dict)
    split: Split
    checkpoint: str | None = None
    seed: int | None = None
    score: float | None = None
    counterpart: dict[str, Any] | None = None
    # HSP (`hidden_utility` in a self-play config): the event weights its seat was rewarded by, {event: weight}.
    hidden_utility: dict[str, float] | None = None

    @model_serializer(mode="wrap")
    def _dump(self, handler: Any) -> dict[str, Any]:
        # Only HSP's partners have event weights: other manifests stay as they were before the field existed.
        data = handler(self)
        if data.get("hidden_utility") is None:
            data.pop("hidden_utility", None)
        return data

    def build(self) -> Partner:
        """Return the `Partner` this entry describes."""
        return partner_from_spec({"name": self.name, "kind": self.kind, "params": self.params})

    def resolve_paths(self, base: Path) -> None:
        """Make relative `checkpoint` paths (entry, params, counterpart) absolute against `base`."""

        def absolute(p: str | None) -> str | None:
            return p if p is None or Path(p).is_absolute() else str((base / p).resolve())

        self.checkpoint = absolute(self.checkpoint)
        if "checkpoint" in self.params:
            self.params["checkpoint"] = absolute(self.params["checkpoint"])
        if self.counterpart and "checkpoint" in self.counterpart.get("params", {}):
            self.counterpart["params"]["checkpoint"] = absolute(self.counterpart["params"]["checkpoint"])


class Population(BaseModel):
    """A named set of partners for one game configuration, split into train and test."""

    model_config = ConfigDict(extra="forbid")

    name: str
    env: str
    env_config: dict[str, Any] = Field(default_factory=dict)
    # The seat its partners play; in a game of more than two seats, every seat but the ego's, in order (a list).
    partner_agent: str | list[str] = "player_1"
    description: str = ""
    partners: list[PartnerEntry]

    @property
    def partner_agents(self) -> list[str]:
        """The partner seats, one or more: every seat a partner of this population plays, in order."""
        return [self.partner_agent] if isinstance(self.partner_agent, str) else list(self.partner_agent)

    def teams(self, split: Split | None = None) -> list[tuple[str, list[PartnerEntry]]]:
        """(name, one entry per partner seat) for every team of `split`'s partners in seat order; one seat: each partner alone."""
        combos = teams_of(self.entries(split), len(self.partner_agents))
        return [(team_name([e.name for e in combo]), list(combo)) for combo in combos]

    def ego_agent(self, agents: list[str]) -> str:
        """The seat of the game's `agents` that no partner of this population plays (the ego's)."""
        return next(a for a in agents if a not in self.partner_agents)

    def seated(self, team: list[PartnerEntry]) -> dict[str, Partner]:
        """A team (one entry per partner seat, as `teams` gives it) built and seated: partner seat -> its player."""
        return {seat: entry.build() for seat, entry in zip(self.partner_agents, team, strict=True)}

    def entries(self, split: Split | None = None) -> list[PartnerEntry]:
        """Return the entries of `split` (all entries if None), in manifest order."""
        return [e for e in self.partners if split is None or e.split == split]

    def build(self, split: Split | None = None) -> list[Partner]:
        """Return the `Partner` objects of `split` (all if None)."""
        return [e.build() for e in self.entries(split)]

    def validate_partners(self) -> None:
        """Raise ValueError unless the env is registered, names are unique and every partner builds."""
        try:
            env_factory(self.env)
        except ValueError as exc:
            raise ValueError(f"population {self.name!r}: {exc}") from None
        seen: set[str] = set()
        for e in self.partners:
            if e.name in seen:
                raise ValueError(f"population {self.name!r}: duplicate partner name {e.name!r}")
            seen.add(e.name)
            e.build()

    def save(self, path: str | Path) -> Path:
        """Write the manifest as JSON atomically (a crash never leaves a half-written file)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        return write_text_atomically(path, json.dumps(self.model_dump(), indent=2) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> "Population":
        """Read and validate a JSON or YAML manifest (or a folder holding `population.json`).

        Relative checkpoint paths are taken relative to the manifest's folder. ValueError
        names the file and the bad key.
        """
        path = Path(path)
        if _exists(path) and path.is_dir():
            path = path / POPULATION_FILE
        if not _exists(path) or not path.is_file():
            raise ValueError(f"population manifest {str(path)!r} does not exist")
        # A stage asks for the same manifest once per curve (thousands in a 10-seed plan), and reading one builds every
        # partner (a trained one loads its network): read and check each version of a file once per process.
        return read_once(path, cls._read, _LOADED).model_copy(deep=True)

    @classmethod
    def _read(cls, path: Path) -> "Population":
        text = path.read_text()
        try:
            data = json.loads(text)  # what `save` writes; ~40x faster than the YAML parser
        except json.JSONDecodeError:
            try:
                data = yaml.safe_load(text)  # YAML is a superset of JSON
            except yaml.YAMLError as exc:
                raise ValueError(f"population manifest {str(path)!r} is not valid JSON/YAML: {exc}") from None
        try:
            pop = cls.model_validate(data)
        except ValidationError as exc:
            raise ValueError(f"population manifest {str(path)!r}: {describe(exc)}") from None
        for entry in pop.partners:
            entry.resolve_paths(path.parent)
        pop.validate_partners()
        return pop


_LOADED: dict[FileVersion, Population] = {}  # each manifest version, as read
_BUILTINS: dict[str, Callable[[], Population]] = {}
# Built-ins that exist only after a step on the user's machine (trained human proxies): listed once `ready()` says so.
_READY: dict[str, Callable[[], bool]] = {}


def parse_team(pop: Population, partner: str) -> tuple[str, ...]:
    """The team `partner` names in a game of several partner seats: one name per seat joined by '+', or one name for every seat."""
    seats, known = pop.partner_agents, [e.name for e in pop.partners]
    names = partner.split(TEAM_SEPARATOR)
    if len(names) == 1:
        names = names * len(seats)
    if len(names) != len(seats):
        raise ValueError(
            f"partners: {partner!r} names {len(names)} partners, but population {pop.name!r} has {len(seats)} partner seats "
            f"{seats}: give one partner for every seat, or one per seat joined by {TEAM_SEPARATOR!r} (e.g. "
            f"{TEAM_SEPARATOR.join(known[:1] * len(seats))!r})"
        )
    unknown = sorted(set(names) - set(known))
    if unknown:
        raise ValueError(f"partners: population {pop.name!r} has no partner(s) {unknown} (in {partner!r}); it has {known}")
    return tuple(names)


def refuse_existing(folder: Path, overwrite: bool, name_option: str = "name") -> None:
    """ValueError naming `folder` when a population folder is there and `overwrite` is off (checked before any work)."""
    if folder.exists() and not overwrite:
        raise ValueError(f"population folder {str(folder)!r} already exists; choose another {name_option} or pass --overwrite")


def task_suffix(new_task: bool) -> str:
    """What a built-in population's name ends with on its game's new task (zero-shot finds it by that name)."""
    return "-newtask" if new_task else ""


def register_builtin(name: str, builder: Callable[[], Population], ready: Callable[[], bool] | None = None) -> None:
    """Make `builder()` addressable as the population `name`; with `ready`, `names()` lists it only while `ready()` is true.

    `get(name)` always calls `builder`, so a built-in that is not ready says itself what to run first.
    """
    _BUILTINS[name] = builder
    if ready is not None:
        _READY[name] = ready


def is_builtin(name: str) -> bool:
    """Whether `name` is a registered built-in population, loadable now or not (see `register_builtin`'s `ready`)."""
    return name in _BUILTINS


def names() -> list[str]:
    """Return the built-in population names that can be loaded now, in registration order."""
    return [name for name in _BUILTINS if name not in _READY or _READY[name]()]


def _exists(path: Path) -> bool:
    """`path.exists()`, but a name the file system refuses (too long, say) is a file that does not exist.

    `Path.exists` raises OSError for ENAMETOOLONG; a config's population string is user input.
    """
    try:
        return path.exists()
    except OSError:
        return False


def population_ref(name_or_path: str) -> str:
    """`name_or_path` as the stages hand it to their trials: a built-in's name as is, an existing manifest's path made absolute.

    Tune runs each trial in its own working folder, so a path relative to where a command
    started would name nothing there.
    """
    if name_or_path in _BUILTINS or not _exists(Path(name_or_path)):
        return name_or_path
    return str(Path(name_or_path).resolve())


def with_absolute_paths(raw: dict[str, Any], key: str) -> dict[str, Any]:
    """Config `raw` with its population `key` (a name or path, a grid of them, or absent) passed through `population_ref`."""
    value = raw.get(key)
    if value is None:
        return raw
    return {**raw, key: {GRID_KEY: [population_ref(v) for v in value[GRID_KEY]]} if is_grid(value) else population_ref(value)}


def get(name_or_path: str | Path) -> Population:
    """Return the built-in population `name_or_path`, or load the manifest at that path."""
    if not str(name_or_path).strip():  # Path("") is the working folder, which would be searched for a manifest
        raise ValueError(f"population must name a built-in ({', '.join(names())}) or a manifest file, got {str(name_or_path)!r}")
    if str(name_or_path) in _BUILTINS:
        return _BUILTINS[str(name_or_path)]()
    path = Path(name_or_path)
    if path.suffix in (".json", ".yaml", ".yml") or _exists(path):
        return Population.load(path)
    raise ValueError(f"unknown population {str(name_or_path)!r}: not a built-in ({', '.join(names())}) nor a manifest file")


def from_partners(
    name: str,
    env: str,
    env_config: dict[str, Any],
    train: list[Partner],
    test: list[Partner],
    description: str = "",
    partner_agent: str | list[str] = "player_1",
) -> Population:
    """Build a population manifest from partner objects."""
    entries = [PartnerEntry(**p.to_spec(), split=split) for split, group in (("train", train), ("test", test)) for p in group]
    return Population(
        name=name, env=env, env_config=env_config, partner_agent=partner_agent, description=description, partners=entries
    )
