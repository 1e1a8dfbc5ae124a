"""Evaluation sets: the fixed partners a method is scored against, per game, as manifests that say how they were built.

Each game with sets ships two, disjoint (`disjoint`), in `tune_configs/eval_sets/<game>_<role>.yaml`:
a **validation** set to tune against and a **held-out** set to report, as jax-aht fixes them
per task. A set is a YAML manifest:

    name: bandit-heldout
    role: heldout                      # or validation
    env: bandit
    env_config: {symmetric: 2}
    partner_agent: player_1            # the seat the partners play (k seats: a list); the ego plays the other
    built_by: how the set was made (the generator, the command, the choices)
    description: what it holds and why
    partners:                          # scripted partners: a kind with its parameters
      - {name: conv-low-high, kind: bandit_convention, params: {arms: [0, 5, 2, 3]}}
    populations:                       # members of a population: a built-in name or a population folder
      - {population: populations/bandit-s2-selfplay, split: test}   # optional `members: [names]`, and
        # `made_by`: the command that trains a folder the set needs (said when the folder is missing)
    bounds: {conv-low-high: 1.0}       # only where the game has no exact best-response bound (below)
    bounds_by: how the bounds were measured (the commands)

With several partner seats (Level-Based Foraging: `partner_agent: [player_1, player_2]`) the
ego meets every **team** of the set's partners, one per partner seat (`Population.teams`; `H3+H4`), as
`rllib-conv adapt` does by default. A game without an exact best-response bound (the record's
`best_response_return`; any game of more than two seats) is scored against the bounds the set
declares per partner or team, with `bounds_by` saying how they were measured (a best response
trained against each, as jax-aht's are): not an exact bound, so a score can exceed 1.

Trained partners (self-play seeds) enter through `populations`: the manifest names a
population folder (`rllib-conv partners train` wrote it) rather than carrying weights.
`resolve` turns a set into a `Population` (every member in split `test`), so everything that
plays populations plays a set.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, PositiveFloat, ValidationError, model_validator

from rllib_conv.common.config_files import describe
from rllib_conv.common.resources import evaluation_set_file, evaluation_sets
from rllib_conv.partners.population import PartnerEntry, Population, Split, get, is_builtin, names

Role = Literal["heldout", "validation"]
ROLES: tuple[str, ...] = ("heldout", "validation")
MEMBER_SEPARATOR = "/"  # a population member's name in a set: `<population>/<member>`
# ... and in the population `training_population` makes of a set: "/" would split a module's folder on disk.
TRAINING_SEPARATOR = "."


class _Manifest(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SetPartner(_Manifest):
    """A partner the set names directly: a kind (scripted, or `trained_policy` with its checkpoint) and its parameters."""

    name: str = Field(min_length=1)
    kind: str
    params: dict[str, Any] = Field(default_factory=dict)


class SetPopulation(_Manifest):
    """Members of a population, a built-in name or a manifest or population folder (relative to the set's file)."""

    population: str = Field(min_length=1)
    split: Split | None = None  # None: both splits
    members: list[str] | None = None  # None: every member of the split
    made_by: str = ""  # the command that makes the population (a trained one the set needs but does not ship)


class EvaluationSet(_Manifest):
    """One evaluation set: a role, a game, the seat its partners play, how it was built, and its partners."""

    name: str = Field(min_length=1)
    role: Role
    env: str
    env_config: dict[str, Any] = Field(default_factory=dict)
    partner_agent: str | list[str] = "player_1"
    built_by: str = Field(min_length=1)
    description: str = ""
    partners: list[SetPartner] = Field(default_factory=list)
    populations: list[SetPopulation] = Field(default_factory=list)
    # Declared best-response bounds per partner (k seats: per team), for games without an exact one.
    bounds: dict[str, PositiveFloat] = Field(default_factory=dict)
    bounds_by: str = ""
    source: str = Field("", exclude=True)  # the file it was read from (relative population paths start there)

    @model_validator(mode="after")
    def _bounds_say_how(self) -> "EvaluationSet":
        if self.bounds and not self.bounds_by.strip():
            raise ValueError("bounds_by: say how the declared bounds were measured (the commands that made them)")
        return self

    def resolve(self) -> Population:
        """The set as a `Population` (every member in split `test`); ValueError naming the set's file and the problem."""
        entries = [PartnerEntry(name=p.name, kind=p.kind, params=p.params, split="test") for p in self.partners]
        for ref in self.populations:
            entries += self._members(ref)
        if not entries:
            raise ValueError(f"{self._where()}: the set has no partners")
        pop = Population(
            name=self.name,
            env=self.env,
            env_config=self.env_config,
            partner_agent=self.partner_agent,
            description=self.description,
            partners=entries,
        )
        try:
            pop.validate_partners()
        except (TypeError, ValueError) as exc:  # an unknown kind, a bad parameter, a duplicate name
            raise ValueError(f"{self._where()}: {' '.join(str(exc).split())}") from None
        stray = sorted(set(self.bounds) - {name for name, _ in pop.teams()})
        if stray:
            raise ValueError(f"{self._where()}: bounds for {stray}, which are not partners (or teams) of the set")
        return pop

    def training_population(self, name: str | None = None) -> Population:
        """The set's partners as a population to train with (every member in split `train`), named `name` (default
        `<set>-partners`): an ego trained with it is a trained best response, the bounds a set declares. A population
        member `<population>/<member>` is named `<population>.<member>` there (a module ID becomes a folder on disk)."""
        pop = self.resolve()
        entries = [
            e.model_copy(update={"name": e.name.replace(MEMBER_SEPARATOR, TRAINING_SEPARATOR), "split": "train"})
            for e in pop.partners
        ]
        about = f"the partners of evaluation set {self.name!r} ({self.role}), every one to train with"
        return pop.model_copy(update={"name": name or f"{self.name}-partners", "description": about, "partners": entries})

    def waiting_for(self) -> list[str]:
        """The built-in populations the set takes members of that cannot load yet (human proxies not trained)."""
        return [
            ref.population
            for ref in self.populations
            if (t := self._target(ref)) == ref.population and is_builtin(t) and t not in names()
        ]

    def _target(self, ref: SetPopulation) -> str:
        # A folder beside the set's file wins, so a set and its populations can move together.
        local = (Path(self.source).parent if self.source else Path.cwd()) / ref.population
        return str(local) if local.exists() else ref.population

    def _members(self, ref: SetPopulation) -> list[PartnerEntry]:
        target = self._target(ref)
        if ref.made_by and not is_builtin(target) and not Path(target).exists():
            raise ValueError(
                f"{self._where()}: population {ref.population!r} does not exist yet: run `{ref.made_by.strip()}` first"
            )
        try:
            pop = get(target)
        except ValueError as exc:
            raise ValueError(f"{self._where()}: population {ref.population!r}: {' '.join(str(exc).split())}") from None
        if (pop.env, pop.partner_agent) != (self.env, self.partner_agent):
            raise ValueError(
                f"{self._where()}: population {ref.population!r} is for {pop.env} seat {pop.partner_agent}, "
                f"the set for {self.env} seat {self.partner_agent}"
            )
        chosen = pop.entries(ref.split)
        if ref.members is not None:
            missing = sorted(set(ref.members) - {e.name for e in chosen})
            if missing:
                raise ValueError(
                    f"{self._where()}: population {ref.population!r} has no member(s) {missing} in split {ref.split}"
                )
            chosen = [e for e in chosen if e.name in ref.members]
        return [e.model_copy(update={"name": f"{pop.name}{MEMBER_SEPARATOR}{e.name}", "split": "test"}) for e in chosen]

    def _where(self) -> str:
        return f"evaluation set {self.source or self.name!r}"


def load_set(path: str | Path) -> EvaluationSet:
    """Read and validate an evaluation-set manifest; ValueError naming the file and the bad key."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"evaluation set {str(path)!r} does not exist or is not a file")
    try:
        data = yaml.safe_load(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise ValueError(f"evaluation set {str(path)!r} is not valid YAML ({' '.join(str(exc).split())[:200]})") from None
    if not isinstance(data, dict):
        raise ValueError(f"evaluation set {str(path)!r}: expected a mapping (name, role, env, ...), got {type(data).__name__}")
    try:
        return EvaluationSet.model_validate({**data, "source": str(path)})
    except ValidationError as exc:
        raise ValueError(f"evaluation set {str(path)!r}: {describe(exc)}") from None


def shipped_set(game: str, role: str) -> EvaluationSet:
    """The shipped `role` set (heldout, validation) of `game`; ValueError when the game has none."""
    name = f"{game}_{role}.yaml"
    if name not in evaluation_sets():
        have = sorted({n.rsplit("_", 1)[0] for n in evaluation_sets()})
        raise ValueError(
            f"no shipped {role} set for game {game!r} (games with sets: {', '.join(have)}); give a set manifest file instead"
        )
    return load_set(evaluation_set_file(name))


def set_named(name_or_path: str) -> EvaluationSet:
    """A manifest file, or a shipped set by its file name (`overcooked_heldout`); ValueError listing the shipped ones."""
    if Path(name_or_path).is_file():
        return load_set(name_or_path)
    shipped = f"{name_or_path}.yaml"
    if shipped in evaluation_sets():
        return load_set(evaluation_set_file(shipped))
    have = ", ".join(n.removesuffix(".yaml") for n in evaluation_sets())
    raise ValueError(f"{name_or_path!r} is neither an evaluation-set manifest file nor a shipped set ({have})")


def find_set(name_or_path: str, game: str) -> EvaluationSet:
    """`heldout` or `validation` (the shipped set of `game`), or a manifest file; ValueError naming what is wrong."""
    if name_or_path in ROLES:
        return shipped_set(game, name_or_path)
    if Path(name_or_path).is_file():
        return load_set(name_or_path)
    raise ValueError(f"{name_or_path!r} is neither {' nor '.join(ROLES)} nor an evaluation-set manifest file")


def identity(entry: PartnerEntry) -> str:
    """What makes two partners the same player: their kind and parameters (names aside)."""
    return json.dumps({"kind": entry.kind, "params": entry.params}, sort_keys=True)


def overlap(a: Population, b: Population) -> list[str]:
    """The members of `a` that `b` also holds (the same name, or the same kind and parameters)."""
    names, players = {e.name for e in b.partners}, {identity(e) for e in b.partners}
    return [e.name for e in a.partners if e.name in names or identity(e) in players]


def disjoint(a: Population, b: Population) -> bool:
    """Whether two sets share no partner (by name or by kind and parameters): a validation set must not leak the held-out one."""
    return not overlap(a, b)
