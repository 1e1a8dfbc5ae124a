"""The paper's experiment plans: one YAML per game (`tune_configs/plan_<game>.yaml`), read and checked here.

A plan names what `rllib-conv reproduce` trains, adapts and evaluates for one game: the
trained-ego variants (`methods`: label -> experiment settings), the adaptation-only variants,
and, at each scale (`full`, `quick`), the populations with their methods, the self-play
populations, the zero-shot populations and the overrides. `plan_for` turns a file into a
`Plan`; `narrow` keeps part of it (`--populations`, `--methods`). See `plan_bandit.yaml`'s
header for the keys.

A self-play entry with `populations: N` (N > 1) stands for N independently trained self-play
populations, `<name>-p0` ... `<name>-p<N-1>`, equal in every setting but their pair seeds
(`seeds.population_seed`); the plan records them as one group (`Plan.population_groups`,
plan.json's `population_groups`), which the report pools with the population as a level
above the seed. With N = 1 (the default) the population keeps its plain name, so the run
folders of earlier plans are read as before. `full.seeds` declares, before the run, the
seeds the plan's claims need: `--seeds` defaults to it, and the report flags a run with fewer. Any registered game runs from a plan file given as `path` (a game
named by import path included); `reproduce all` runs the games the package ships a plan for.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import Field, NonNegativeFloat, PositiveInt, ValidationError, model_validator

from rllib_conv import envs, partners
from rllib_conv.adaptation.registry import FRESH, check_game, check_information
from rllib_conv.common import config_files
from rllib_conv.common.config_files import Strict
from rllib_conv.common.resources import available, config_file
from rllib_conv.common.seeds import population_seed
from rllib_conv.partners.evaluation_sets import Role, shipped_set
from rllib_conv.partners.population import parse_team, team_name
from rllib_conv.pipelines.evaluate_config import check_fit
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

# The registered games the package ships a plan for: what `reproduce all` runs.
GAMES = tuple(g.name for g in envs.games() if f"plan_{g.name}.yaml" in available())
# The key of a self-play entry that asks for several independently trained populations (not a self-play setting).
POPULATIONS_KEY = "populations"
DEFAULT_SEEDS = 3  # seeds of a full plan that declares none (`--seeds` unset)


def population_names(name: str, count: int) -> list[str]:
    """The populations of self-play entry `name` trained `count` times: `<name>-p0`, ...; `[name]` when `count` is 1."""
    return [name] if count == 1 else [f"{name}-p{p}" for p in range(count)]


def population_count(entry: dict[str, Any]) -> int:
    """How many independent populations self-play entry `entry` trains (its `populations`, default 1)."""
    return int(entry.get(POPULATIONS_KEY, 1))


@dataclass
class TrainedVariant:
    """One trained-ego variant of a plan: a label for tables and the experiment keys it sets."""

    label: str
    settings: dict[str, Any]


@dataclass
class AdaptVariant:
    """Adaptation only: adaptation `settings` applied to the trained egos of `base` (nothing more is trained)."""

    label: str
    base: TrainedVariant
    settings: dict[str, Any]


@dataclass
class Plan:
    """What to run for one game at one scale."""

    game: str
    seeds: list[int]
    paper_method: TrainedVariant  # always run: learning from scratch and zero-shot start from its egos
    populations: dict[str, list[TrainedVariant]]  # built-in population -> methods trained and adapted on it
    selfplay: list[dict[str, Any]]  # self-play configs (overrides of tune_configs/selfplay_<game>.yaml)
    selfplay_methods: list[TrainedVariant] = field(default_factory=list)
    population_overrides: dict[str, dict[str, Any]] = field(default_factory=dict)  # training settings per population
    zeroshot_populations: list[str] = field(default_factory=list)
    zeroshot_methods: list[TrainedVariant] = field(default_factory=list)
    # Run for every population whose methods include their base (the paper method always does).
    adapt_variants: list[AdaptVariant] = field(default_factory=list)
    # Populations left out of the marginals: their partners' conventions are not uniform over
    # optimal actions, so the distance to that uniform distribution measures nothing the regulariser aims at.
    no_marginals: list[str] = field(default_factory=list)
    adapt_partners: int | None = None  # test partners per population (None: all)
    adapt_teams: dict[str, list[str]] = field(default_factory=dict)  # population -> the teams its egos adapt to (k seats)
    train_overrides: dict[str, Any] = field(default_factory=dict)
    train_steps: int | None = None  # every ego's training env steps, over any default or override (None: keep them)
    adapt_overrides: dict[str, Any] = field(default_factory=dict)
    zeroshot_overrides: dict[str, Any] = field(default_factory=dict)
    quick: bool = False
    # The report's "no worse" margin in the game's score units (None: 1% of the game's maximum score); declared before the run.
    no_worse_margin: float | None = None
    # Population -> other populations whose test members the egos trained on it also adapt to (experiment `<other>__<label>`).
    adapt_to: dict[str, list[str]] = field(default_factory=dict)
    heldout: "HeldoutSpec | None" = None  # the held-out evaluation stage (`pipelines/heldout.py`), if any
    # Self-play entry -> its independently trained populations (`<name>-p0`, ...), for entries with `populations` > 1.
    population_groups: dict[str, list[str]] = field(default_factory=dict)
    declared_seeds: int | None = None  # the seeds the plan's claims need, declared before the run (`full.seeds`)
    # Population -> evaluation sets (heldout, validation: the game's shipped ones) its egos meet (`rllib-conv evaluate`).
    evaluate: dict[str, list[str]] = field(default_factory=dict)
    evaluate_overrides: dict[str, Any] = field(default_factory=dict)  # `EvaluateConfig` settings (episodes, resamples)


# --- the file's schema ------------------------------------------------------------------------


class AdaptVariantSpec(Strict):
    """An adaptation-only variant in a plan file: the trained variant it adapts, and its adaptation settings."""

    base: str
    settings: dict[str, Any] = Field(default_factory=dict)


class HeldoutAgentSpec(Strict):
    """One agent of the held-out evaluation: exactly one of its sources (see `pipelines/heldout.py`)."""

    selfplay: str | None = Field(None, description="a self-play population of this plan: each pair's ego-seat player")
    trained: str | None = Field(None, description="a method label of this plan: its single-network egos (agg, maml)")
    population: str | None = Field(None, description="with `trained`: the population those egos trained on")
    members: str | None = Field(None, description="a population whose members themselves take the ego seat")

    @model_validator(mode="after")
    def _one_source(self) -> "HeldoutAgentSpec":
        given = [k for k in ("selfplay", "trained", "members") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one of selfplay, trained, members; got {given or 'none'}")
        if (self.trained is None) != (self.population is None):
            raise ValueError("`trained` and `population` go together: the method label and the population it trained on")
        return self


class HeldoutSpec(Strict):
    """The held-out evaluation: named agents, each seed with every member of `partners`, and the claims to judge."""

    partners: str = Field(description="the held-out population every agent plays with (all its members)")
    episodes: PositiveInt = Field(20, description="scored episodes per (agent seed, partner)")
    agents: dict[str, HeldoutAgentSpec]
    claims: list[tuple[str, str]] = Field(default_factory=list, description='pairs [A, B], each the claim "A beats B"')

    @model_validator(mode="after")
    def _claims_name_agents(self) -> "HeldoutSpec":
        unknown = sorted({x for pair in self.claims for x in pair} - set(self.agents))
        if unknown:
            raise ValueError(f"claims: {unknown} are not agents; agents: {sorted(self.agents)}")
        return self


class ScaleSpec(Strict):
    """One scale of a plan file (`full` or `quick`); method lists name labels of the file's `methods`."""

    seeds: PositiveInt | None = Field(
        None,
        description="the seeds this scale's claims need, declared before the run (full scale only): `--seeds` defaults "
        "to it and the report flags a run with fewer",
    )
    populations: dict[str, list[str]] = Field(default_factory=dict)
    selfplay: list[dict[str, Any]] = Field(
        default_factory=list,
        description="self-play populations: overrides of tune_configs/selfplay_<game>.yaml, each with a `name`; "
        "`populations: N` trains N independent ones, <name>-p0 ... <name>-p<N-1>",
    )
    selfplay_methods: list[str] = Field(default_factory=list)
    zeroshot_populations: list[str] = Field(default_factory=list)
    zeroshot_methods: list[str] = Field(default_factory=list)
    adapt_variants: list[str] = Field(default_factory=list)
    no_marginals: list[str] = Field(default_factory=list)
    adapt_partners: PositiveInt | None = None
    adapt_teams: dict[str, list[str]] = Field(
        default_factory=dict,
        description="population -> the teams its egos adapt to (`H1+H3`: one partner per partner seat, test or train members) "
        "instead of every team of its test members; e.g. teams with a member the egos trained with (head_init known-seats)",
    )
    population_overrides: dict[str, dict[str, Any]] = Field(default_factory=dict)
    train_overrides: dict[str, Any] = Field(default_factory=dict)
    adapt_overrides: dict[str, Any] = Field(default_factory=dict)
    zeroshot_overrides: dict[str, Any] = Field(default_factory=dict)
    adapt_to: dict[str, list[str]] = Field(default_factory=dict)
    heldout: HeldoutSpec | None = None
    evaluate: dict[str, list[Role]] = Field(
        default_factory=dict,
        description="population -> the game's shipped evaluation sets (heldout, validation) that every method trained on it "
        "meets after training (`rllib-conv evaluate`: normalised scores, mean and IQM over seeds)",
    )
    evaluate_overrides: dict[str, Any] = Field(default_factory=dict, description="settings of `rllib-conv evaluate`")

    @model_validator(mode="after")
    def _selfplay_entries(self) -> "ScaleSpec":
        for i, entry in enumerate(self.selfplay):
            if not isinstance(entry.get("name"), str):
                raise ValueError(f"selfplay[{i}]: every self-play entry needs a `name`")
            count = entry.get(POPULATIONS_KEY, 1)
            if isinstance(count, bool) or not isinstance(count, int) or count < 1:
                raise ValueError(f"selfplay[{i}] ({entry['name']}): `populations` must be a positive integer, got {count!r}")
        return self


class PlanFile(Strict):
    """A plan file: the game, its variants and its two scales; every label it uses must be defined."""

    game: str
    paper_method: str
    methods: dict[str, dict[str, Any]]
    adapt_variants: dict[str, AdaptVariantSpec] = Field(default_factory=dict)
    no_worse_margin: NonNegativeFloat | None = None
    full: ScaleSpec
    quick: ScaleSpec

    @model_validator(mode="after")
    def _labels_defined(self) -> "PlanFile":
        def check(labels: list[str], known: dict, where: str) -> None:
            unknown = [x for x in labels if x not in known]
            if unknown:
                raise ValueError(f"{where}: {unknown} not defined; defined: {sorted(known)}")

        check([self.paper_method], self.methods, "paper_method")
        check([v.base for v in self.adapt_variants.values()], self.methods, "adapt_variants.*.base")
        for scale in ("full", "quick"):
            spec: ScaleSpec = getattr(self, scale)
            for population, labels in spec.populations.items():
                check(labels, self.methods, f"{scale}.populations.{population}")
            check(spec.selfplay_methods, self.methods, f"{scale}.selfplay_methods")
            check(spec.zeroshot_methods, self.methods, f"{scale}.zeroshot_methods")
            check(spec.adapt_variants, self.adapt_variants, f"{scale}.adapt_variants")
            trained = {**spec.populations, **{sp.get("name"): spec.selfplay_methods for sp in spec.selfplay}}
            check(list(spec.adapt_to), trained, f"{scale}.adapt_to")
            check(list(spec.evaluate), spec.populations, f"{scale}.evaluate")
            check(list(spec.adapt_teams), spec.populations, f"{scale}.adapt_teams")
            targets: dict[tuple[str, str], str] = {}
            for source, others in spec.adapt_to.items():
                for other in others:
                    for label in trained[source]:
                        if targets.setdefault((other, label), source) != source:  # both would write `<other>__<label>`
                            raise ValueError(
                                f"{scale}.adapt_to: {label!r} egos of {targets[other, label]!r} and {source!r} "
                                f"would both adapt to {other!r}; give one of them another label"
                            )
            if scale == "quick" and spec.seeds is not None:
                raise ValueError("quick.seeds: the quick plan runs seed 0 alone; declare the seeds under `full`")
            if spec.heldout is not None:
                selfplay = {sp.get("name"): population_count(sp) for sp in spec.selfplay}
                for name, agent in spec.heldout.agents.items():
                    if agent.selfplay is not None and agent.selfplay not in selfplay:
                        raise ValueError(
                            f"{scale}.heldout.agents.{name}: {agent.selfplay!r} is not a self-play population of the plan"
                        )
                    if agent.selfplay is not None and selfplay[agent.selfplay] > 1:
                        raise ValueError(
                            f"{scale}.heldout.agents.{name}: {agent.selfplay!r} trains {selfplay[agent.selfplay]} populations; "
                            "a held-out agent is one self-play population"
                        )
                    if agent.trained is not None and agent.trained not in trained.get(agent.population, []):
                        raise ValueError(
                            f"{scale}.heldout.agents.{name}: the plan trains no {agent.trained!r} on {agent.population!r}"
                        )
        return self


def shipped_plan(game: str) -> Path:
    """The plan file of `game` that the package ships (`tune_configs/plan_<game>.yaml`)."""
    return config_file(f"plan_{game}.yaml")


def read_plan_file(path: str | Path) -> PlanFile:
    """Read and validate a plan YAML; ValueError naming the file and the bad key."""
    raw = config_files.read_yaml(path, "plan file")
    try:
        return PlanFile.model_validate(raw)
    except ValidationError as exc:
        raise ValueError(f"plan file {str(path)!r}: {config_files.describe(exc)}") from None


def plan_for(
    game: str, seeds: int | None = None, quick: bool = False, train_steps: int | None = None, path: str | Path | None = None
) -> Plan:
    """The plan of `game` from `path` (default: the shipped plan), at the paper's scale or, with `quick`, the small one.

    Egos train for the game's budget (its record's `training_defaults()`) unless
    `train_steps` sets another; the full plan runs seeds 0..`seeds`-1 (default: the seeds the
    plan declares, `full.seeds`, else 3), the quick one seed 0. Self-play entries with
    `populations` > 1 become their populations (`expand_selfplay`).
    """
    record = envs.game(game)  # ValueError naming the registered games
    if path is None and game not in GAMES:
        raise ValueError(
            f"game {game!r} has no shipped plan (games with one: {', '.join(GAMES)}, or all); give a plan file with --plan"
        )
    if seeds is not None and seeds < 1:
        raise ValueError(f"--seeds: expected at least 1 seed per method, got {seeds}")
    if train_steps is not None and train_steps < 1:
        raise ValueError(f"--train-steps: expected a positive number of env steps, got {train_steps}")
    source = path if path is not None else shipped_plan(game)
    spec = read_plan_file(source)
    if spec.game != game:
        raise ValueError(f"--plan: {str(source)!r} is a plan for {spec.game!r}, not {game!r}")
    variants = {label: TrainedVariant(label, settings) for label, settings in spec.methods.items()}
    adapt_variants = {label: AdaptVariant(label, variants[v.base], v.settings) for label, v in spec.adapt_variants.items()}
    scale = spec.quick if quick else spec.full
    if scale.zeroshot_populations and not record.new_task:
        raise ValueError(
            f"plan file {str(source)!r}: zero-shot populations for {game!r}, a game without a new task (its record's new_task)"
        )
    for label in scale.adapt_variants:
        try:
            start = adapt_variants[label].settings.get("head_init", FRESH)
            check_information(start, game)
            # The ego's seat of every built-in population; `rllib-conv adapt` checks each curve's own seat again.
            check_game(start, game, {}, "player_0")
        except ValueError as exc:
            raise ValueError(f"plan file {str(source)!r}: adapt_variants.{label}: {exc}") from None
    adapt_teams = {}  # each team by its canonical name (`H2` in every seat: `H2+H2`)
    for population, teams in scale.adapt_teams.items():
        pop = partners.get(population)
        if len(pop.partner_agents) == 1:
            raise ValueError(
                f"plan file {str(source)!r}: adapt_teams.{population}: a team needs several partner seats; it has one"
            )
        try:
            adapt_teams[population] = [team_name(parse_team(pop, team)) for team in teams]
        except ValueError as exc:
            raise ValueError(f"plan file {str(source)!r}: adapt_teams.{population}: {exc}") from None
    for population, roles in scale.evaluate.items():
        pop = partners.get(population)
        for role in roles:
            try:
                eval_set = shipped_set(game, role)
                if eval_set.waiting_for():  # e.g. human proxies not trained yet: the stage checks the fit when it runs
                    continue
                check_fit(eval_set, eval_set.resolve(), pop.env, pop.env_config, pop.partner_agent)
            except ValueError as exc:
                raise ValueError(f"plan file {str(source)!r}: evaluate.{population}: {role}: {exc}") from None
    if seeds is None:
        seeds = spec.full.seeds or DEFAULT_SEEDS
    selfplay, groups = expand_selfplay(scale.selfplay, game)
    return Plan(
        game=game,
        seeds=[0] if quick else list(range(seeds)),
        paper_method=variants[spec.paper_method],
        populations={population: [variants[x] for x in labels] for population, labels in scale.populations.items()},
        selfplay=selfplay,
        selfplay_methods=[variants[x] for x in scale.selfplay_methods],
        population_overrides=scale.population_overrides,
        zeroshot_populations=scale.zeroshot_populations,
        zeroshot_methods=[variants[x] for x in scale.zeroshot_methods],
        adapt_variants=[adapt_variants[x] for x in scale.adapt_variants],
        no_marginals=scale.no_marginals,
        adapt_partners=scale.adapt_partners,
        adapt_teams=adapt_teams,
        train_overrides=scale.train_overrides,
        train_steps=train_steps,
        adapt_overrides=scale.adapt_overrides,
        zeroshot_overrides=scale.zeroshot_overrides,
        quick=quick,
        no_worse_margin=spec.no_worse_margin,
        adapt_to=expand_adapt_to(scale.adapt_to, groups),
        heldout=scale.heldout,
        evaluate=scale.evaluate,
        evaluate_overrides=scale.evaluate_overrides,
        population_groups=groups,
        declared_seeds=None if quick else spec.full.seeds,
    )


def expand_selfplay(entries: list[dict[str, Any]], game: str) -> tuple[list[dict[str, Any]], dict[str, list[str]]]:
    """Self-play entries with their `populations` trained apart: (one entry per population, entry name -> population names).

    Population p of an entry trains pairs seeded from `population_seed(seed, p)`, `seed` the
    entry's or else `tune_configs/selfplay_<game>.yaml`'s; everything else is the entry's.
    An entry with one population is kept as it is (no `-p0` suffix, its seed unchanged).
    """
    expanded, groups = [], {}
    for entry in entries:
        settings = {k: v for k, v in entry.items() if k != POPULATIONS_KEY}
        count = population_count(entry)
        if count == 1:
            expanded.append(settings)
            continue
        seed = settings.get("seed", _selfplay_default_seed(game))
        groups[settings["name"]] = population_names(settings["name"], count)
        for p, name in enumerate(groups[settings["name"]]):
            expanded.append({**settings, "name": name, "seed": population_seed(seed, p)})
    return expanded, groups


def _selfplay_default_seed(game: str) -> int:
    """The self-play seed of `game`'s shipped self-play config (the schema's default where it ships none)."""
    if f"selfplay_{game}.yaml" in available():
        seed = config_files.read_yaml(config_file(f"selfplay_{game}.yaml"), "self-play config").get("seed")
        if seed is not None:
            return int(seed)
    return int(SelfPlayConfig.model_fields["seed"].default)


def expand_adapt_to(adapt_to: dict[str, list[str]], groups: dict[str, list[str]]) -> dict[str, list[str]]:
    """`adapt_to` with each self-play entry of several populations replaced by its populations, as source and as target."""

    def members(name: str) -> list[str]:
        return groups.get(name, [name])

    return {m: [t for other in others for t in members(other)] for source, others in adapt_to.items() for m in members(source)}


def narrow(plan: Plan, populations: list[str] | None = None, methods: list[str] | None = None) -> Plan:
    """Keep only the named populations (built-in, self-play or zero-shot ones) and method labels of `plan`.

    The paper method is always kept: learning from scratch and zero-shot start from its runs.
    ValueError naming the unknown ones and the choices.
    """
    if populations:
        known = [*plan.populations, *(sp["name"] for sp in plan.selfplay), *plan.zeroshot_populations, *plan.population_groups]
        unknown = sorted(set(populations) - set(known))
        if unknown:
            raise ValueError(f"--populations: {unknown} not in the {plan.game} plan; choose from {sorted(set(known))}")
        # A self-play entry of several populations names them all.
        populations = [m for name in populations for m in plan.population_groups.get(name, [name])]
        plan.population_groups = {
            k: [m for m in v if m in populations] for k, v in plan.population_groups.items() if set(v) & set(populations)
        }
        plan.populations = {k: v for k, v in plan.populations.items() if k in populations}
        plan.selfplay = [sp for sp in plan.selfplay if sp["name"] in populations]
        plan.zeroshot_populations = [p for p in plan.zeroshot_populations if p in populations]
        plan.adapt_to = {k: v for k, v in plan.adapt_to.items() if k in populations}
    if methods:
        known = {m.label for ms in [*plan.populations.values(), plan.selfplay_methods] for m in ms}
        unknown = sorted(set(methods) - known)
        if unknown:
            raise ValueError(f"--methods: {unknown} not in the {plan.game} plan; choose from {sorted(known)}")
        keep = set(methods) | {plan.paper_method.label}
        plan.populations = {k: [m for m in v if m.label in keep] for k, v in plan.populations.items()}
        plan.selfplay_methods = [m for m in plan.selfplay_methods if m.label in keep]
    if plan.heldout is not None and not all(_kept(plan, a) for a in plan.heldout.agents.values()):
        plan.heldout = None  # its agents would be compared with some of them missing
    return plan


def _kept(plan: Plan, agent: HeldoutAgentSpec) -> bool:
    """Whether a narrowed `plan` still produces held-out agent `agent`."""
    if agent.selfplay is not None:
        return any(sp["name"] == agent.selfplay for sp in plan.selfplay)
    if agent.trained is not None:
        return agent.trained in [m.label for m in plan.populations.get(agent.population, [])]
    return True
