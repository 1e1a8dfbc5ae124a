"""Typed experiment configs: one YAML file per experiment, validated on load.

Any value may be a Tune grid, written `{grid_search: [a, b, ...]}` in YAML. Every
combination is validated before anything runs; errors name the key path
(`ppo.minibatch_size: Input should be greater than 0`). Unset game-dependent fields
(layer size, rollout length, minibatch, epochs, timesteps) take the paper's values for
the game (`GAME_DEFAULTS`).
"""

from __future__ import annotations

import copy
import itertools
from pathlib import Path
from typing import Annotated, Any, Literal

import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    NonNegativeFloat,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    ValidationError,
    model_validator,
)

from rllib_conv.envs.registry import factory as env_factory

Method = Literal["modular", "agg", "no_task_logits", "oracle", "maml"]
# Methods whose ego is one network for all partners (task module + a single head).
SINGLE_HEAD_METHODS = ("agg", "maml")
GRID_KEY = "grid_search"

# The paper's Tables 2-4 and the original code: layer size, rollout steps per partner,
# minibatch, epochs, training env steps.
GAME_DEFAULTS: dict[str, dict[str, int]] = {
    "bandit": {"hidden": 30, "rollout_per_partner": 64, "minibatch_size": 16, "num_epochs": 20, "timesteps": 10_000},
    "blocks": {"hidden": 80, "rollout_per_partner": 640, "minibatch_size": 160, "num_epochs": 5, "timesteps": 1_000_000},
    "hanabi": {"hidden": 500, "rollout_per_partner": 640, "minibatch_size": 160, "num_epochs": 5, "timesteps": 500_000},
}
FALLBACK_DEFAULTS = {"hidden": 64, "rollout_per_partner": 256, "minibatch_size": 64, "num_epochs": 10, "timesteps": 100_000}


def _folder_name(v: str) -> str:
    if not v or any(c in v for c in '/\\<>:"|?* '):
        raise ValueError(f"must be a non-empty folder name without spaces or /\\<>:\"|?*, got {v!r}")
    return v


def _registered_env(v: str) -> str:
    env_factory(v)  # ValueError naming the registered envs
    return v


def _schedule_starts_at_zero(v: Any) -> Any:
    if isinstance(v, list) and (not v or v[0][0] != 0 or any(a[0] >= b[0] for a, b in zip(v, v[1:]))):
        raise ValueError("a schedule must be [[0, value], [step, value], ...] with increasing steps")
    return v


FolderName = Annotated[str, AfterValidator(_folder_name)]
EnvName = Annotated[str, AfterValidator(_registered_env)]
# A constant, or a piecewise-linear schedule [[env_step, value], ...] starting at step 0.
EntropyCoeff = Annotated[NonNegativeFloat | list[tuple[NonNegativeInt, NonNegativeFloat]], AfterValidator(_schedule_starts_at_zero)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=True)


class ModelSettings(_Strict):
    """Network sizes: every layer of both modules has `hidden` units; z has `z_dim` (default hidden)."""

    hidden: PositiveInt | None = None
    z_dim: PositiveInt | None = None


class PPOSettings(_Strict):
    """PPO hyperparameters (defaults: the paper's code, Stable-Baselines3 PPO)."""

    lr: PositiveFloat = 3e-4
    gamma: float = Field(0.99, ge=0.0, le=1.0)
    gae_lambda: float = Field(0.95, ge=0.0, le=1.0)
    clip_param: PositiveFloat = 0.2
    entropy_coeff: EntropyCoeff = 0.0
    vf_loss_coeff: float = Field(0.5, ge=0.0)
    grad_clip: PositiveFloat | None = 0.5
    adam_eps: PositiveFloat = 1e-5
    rollout_per_partner: PositiveInt | None = None
    minibatch_size: PositiveInt | None = None
    num_epochs: PositiveInt | None = None


class RunSettings(_Strict):
    """How long and on what: env steps, env runners, vectorised sub-envs, checkpoints, fault tolerance.

    A remote env runner (`num_env_runners` > 0) that crashes is always restarted and
    training goes on with the others meanwhile. `restart_failed_sub_environments` also
    recreates an env that raises inside a runner (the local one too) instead of failing
    the trial; off by default, since an env that always raises would then loop forever.
    """

    timesteps: PositiveInt | None = None
    num_env_runners: int = Field(0, ge=0)
    num_envs_per_env_runner: PositiveInt = 8
    restart_failed_sub_environments: bool = False
    # Custom Ray resources each trial asks for: {"second_node": 1} runs it only on nodes
    # started with `ray start --resources '{"second_node": N}'`.
    resources: dict[str, PositiveFloat] = Field(default_factory=dict)
    checkpoint_every: PositiveInt = 10
    keep_checkpoints: PositiveInt = 2
    eval_episodes: PositiveInt = 200


class MAMLSettings(_Strict):
    """First-order MAML across training partners (the paper's Table 5 values).

    Each outer step takes the next training partner, runs `inner_iterations` PPO updates
    (learning rate `ppo.lr`, the paper's inner lr 3e-4) from the meta-weights theta, and
    moves theta by `outer_step * (adapted - theta)`.
    """

    inner_iterations: PositiveInt = 4
    outer_step: float = Field(0.25, gt=0.0, le=1.0)


class ExperimentConfig(_Strict):
    """One ego-training experiment: game, partners, method, regulariser, sizes, PPO, run."""

    name: FolderName = "experiment"
    env: EnvName | None = None
    env_config: dict[str, Any] = Field(default_factory=dict)
    population: str
    method: Method = "modular"
    lam: float = Field(0.0, ge=0.0)
    freeze: list[str] = Field(default_factory=list)
    # Learning-rate multiplier for the task module's z layers (0 freezes them, 1 is plain PPO).
    z_lr_scale: float = Field(1.0, ge=0.0)
    # Weight of the head penalty (not in the paper; see MarginalPPOLearner): heads carry conventions only.
    head_l2: float = Field(0.0, ge=0.0)
    seed: int = 0
    model: ModelSettings = Field(default_factory=ModelSettings)
    ppo: PPOSettings = Field(default_factory=PPOSettings)
    run: RunSettings = Field(default_factory=RunSettings)
    maml: MAMLSettings = Field(default_factory=MAMLSettings)

    @model_validator(mode="after")
    def _consistent(self) -> "ExperimentConfig":
        if self.method in ("no_task_logits", "oracle", "maml") and self.lam > 0:
            raise ValueError(f"lam must be 0 for method {self.method!r} (it has no learned task logits to regularise)")
        if self.method != "modular" and self.head_l2 > 0:
            raise ValueError(f"head_l2 must be 0 for method {self.method!r} (only modular heads sit on task logits that can take over)")
        return self

    def resolve(self, game: str) -> "ExperimentConfig":
        """Return a copy for `game` with every unset game-dependent field set to the paper's value."""
        d = GAME_DEFAULTS.get(game, FALLBACK_DEFAULTS)
        out = self.model_copy(deep=True)
        out.env = game
        out.model.hidden = out.model.hidden or d["hidden"]
        for key in ("rollout_per_partner", "minibatch_size", "num_epochs"):
            if getattr(out.ppo, key) is None:
                setattr(out.ppo, key, d[key])
        out.run.timesteps = out.run.timesteps or d["timesteps"]
        return out


class GateSettings(_Strict):
    """The score a self-play pair must reach to be kept, and how it is checked."""

    score: float
    episodes: PositiveInt = 1000
    check_every: PositiveInt = 5
    check_episodes: PositiveInt = 200


class SelfPlayConfig(_Strict):
    """Self-play partner training: `train_pairs + test_pairs` pairs, pair k seeded `seed + k`.

    `ppo.rollout_per_partner` is the rollout length per iteration. With `shared_seats`
    one module plays both seats (Hanabi); otherwise each seat has its own module and the
    `partner_agent` seat of each pair becomes a partner.
    """

    name: FolderName = "selfplay"
    env: EnvName
    env_config: dict[str, Any] = Field(default_factory=dict)
    train_pairs: PositiveInt = 10
    test_pairs: int = Field(10, ge=0)
    seed: int = 0
    pair: int = Field(0, ge=0)
    shared_seats: bool = False
    partner_agent: str = "player_1"
    greedy_partners: bool = True
    model: ModelSettings = Field(default_factory=ModelSettings)
    ppo: PPOSettings = Field(default_factory=PPOSettings)
    run: RunSettings = Field(default_factory=RunSettings)
    gate: GateSettings

    def resolve(self) -> "SelfPlayConfig":
        """Return a copy with the game's defaults filled in (see `ExperimentConfig.resolve`)."""
        as_exp = ExperimentConfig(population="-", model=self.model, ppo=self.ppo, run=self.run).resolve(self.env)
        return self.model_copy(update={"model": as_exp.model, "ppo": as_exp.ppo, "run": as_exp.run})


class AdaptConfig(_Strict):
    """Adapting trained egos to new partners: keep the task module, a fresh head, lam 0.

    `runs` are trained-ego trial folders (or experiment folders: every trial in them).
    Partners are `split` of `population` (default: the population each run trained on),
    optionally only `partners`. `method: scratch` adapts a fresh network instead. The ego
    is evaluated before every update (`every` env steps) up to `steps`, `episodes` episodes
    each (and exactly on the bandit). Unset values take the paper's per-game adaptation
    settings (`ADAPT_DEFAULTS`); `ppo` overrides the run's PPO settings.
    `head_init: pick` (not in the paper; egos with one head per partner) first spends
    `pick_steps` env steps (default `every`) trying the fresh head and every training
    partner's head on the new partner, and adapts from the best (`pipelines/head_pick`).
    """

    name: FolderName = "adapt"
    runs: list[str]
    population: str | None = None
    split: Literal["train", "test"] = "test"
    partners: list[str] | None = None
    method: Literal["scratch"] | None = None
    train_task: bool = True
    head_init: Literal["fresh", "pick"] = "fresh"
    pick_steps: PositiveInt | None = None
    every: PositiveInt | None = None
    steps: PositiveInt | None = None
    episodes: PositiveInt = 200
    ppo: dict[str, Any] = Field(default_factory=dict)
    seed: int = 0
    # Set per Tune trial: which run and which partner this trial adapts.
    run: str | None = None
    partner: str | None = None

    @model_validator(mode="after")
    def _consistent(self) -> "AdaptConfig":
        if self.head_init == "pick" and self.method == "scratch":
            raise ValueError("head_init 'pick' needs the trained ego's heads; method 'scratch' starts from a fresh network")
        if self.pick_steps is not None and self.head_init != "pick":
            raise ValueError(f"pick_steps is set but head_init is {self.head_init!r}; set head_init: pick to use it")
        return self


# The paper's adaptation protocol: evaluate every `every` env steps up to `steps`; one PPO
# update of `minibatch_size` x `num_epochs` per `every` steps (Table 3 and the notes).
ADAPT_DEFAULTS: dict[str, dict[str, int]] = {
    "bandit": {"every": 16, "steps": 240, "minibatch_size": 16, "num_epochs": 50},
    "blocks": {"every": 640, "steps": 25_600, "minibatch_size": 160, "num_epochs": 5},
    "hanabi": {"every": 640, "steps": 25_600, "minibatch_size": 160, "num_epochs": 5},
}


class ZeroShotConfig(_Strict):
    """Zero-shot coordination on a new task with known partners (the paper's three steps).

    1. Fresh heads for the test partners on the old task, task module frozen (`head_steps`,
       regulariser weight `head_lam`, default the run's lam: trained as the training
       partners' heads were, they leave the rules to the task module).
    2. The task module re-trained on the new task with the training partners' heads frozen
       (`task_steps`, regulariser weight `task_lam`, default the run's lam; the z layers
       learn at `task_z_lr_scale` times the learning rate: 1 as in training, 0 frozen);
       `reset_task_logits` re-initialises the task logits layer first, and `task_entropy`
       adds an entropy bonus, so the new rules get explored.
    3. The new task module with the test partners' heads, evaluated on the new task with no
       further training (`episodes` episodes; exactly on the bandit).
    `new_population` defaults to the run's population + "-newtask".
    """

    name: FolderName = "zeroshot"
    runs: list[str]
    new_population: str | None = None
    head_steps: PositiveInt | None = None
    task_steps: PositiveInt | None = None
    reset_task_logits: bool = True
    # Trained heads carry some of the old rules too; without exploration the task module
    # never tries the new rule actions (the original code's 0.49 on the bandit).
    task_entropy: EntropyCoeff = 0.05
    task_lam: NonNegativeFloat | None = None
    task_z_lr_scale: NonNegativeFloat = 1.0
    head_lam: NonNegativeFloat | None = None
    episodes: PositiveInt = 200
    seed: int = 0
    run: str | None = None


# Step 1 runs until the test heads have converged on the old task: on blocks ~19.5 of 20
# by 300k steps (at 100k, BaselineModular's heads, which learn the rules too, reach ~11.5).
ZEROSHOT_DEFAULTS: dict[str, dict[str, int]] = {
    "bandit": {"head_steps": 2_560, "task_steps": 10_000},
    "blocks": {"head_steps": 300_000, "task_steps": 400_000},
}


def _format(exc: ValidationError) -> str:
    return "; ".join(f"{'.'.join(str(p) for p in e['loc']) or '<root>'}: {e['msg']}" for e in exc.errors())


def _is_grid(node: Any) -> bool:
    return isinstance(node, dict) and set(node) == {GRID_KEY}


def _grid_paths(node: Any, path: tuple = ()) -> list[tuple[tuple, list]]:
    """Return (key path, values) of every `{grid_search: [...]}` in a nested dict."""
    if _is_grid(node):
        values = node[GRID_KEY]
        if not isinstance(values, list) or not values:
            raise ValueError(f"{'.'.join(map(str, path))}: grid_search needs a non-empty list, got {values!r}")
        return [(path, values)]
    if isinstance(node, dict):
        return [g for k, v in node.items() for g in _grid_paths(v, (*path, k))]
    return []


def _set_path(node: dict, path: tuple, value: Any) -> None:
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
            _set_path(variant, path, value)
        variants.append(variant)
    return variants


def validate(raw: dict[str, Any], source: str = "config", schema: type[BaseModel] = ExperimentConfig) -> list:
    """Validate every grid combination of `raw` against `schema`; return them. ValueError names the bad key."""
    if not isinstance(raw, dict):
        raise ValueError(f"{source}: expected a mapping of settings, got {type(raw).__name__}")
    out = []
    for variant in expand_grid(raw):
        try:
            out.append(schema.model_validate(variant))
        except ValidationError as exc:
            raise ValueError(f"{source}: {_format(exc)}") from None
    return out


def parse_override(text: str) -> tuple[tuple[str, ...], Any]:
    """Parse `--set key.path=value` (value in YAML syntax) into (path, value)."""
    if "=" not in text:
        raise ValueError(f"--set expects key=value, got {text!r}")
    key, value = text.split("=", 1)
    if not key or any(not part for part in key.split(".")):
        raise ValueError(f"--set expects a dotted key like ppo.lr, got {key!r}")
    return tuple(key.split(".")), yaml.safe_load(value)


def from_dict(raw: dict[str, Any], overrides: list[str] = (), schema: type[BaseModel] = ExperimentConfig, source: str = "arguments") -> dict[str, Any]:
    """Apply `--set` overrides to `raw` and validate it against `schema`; return the raw dict."""
    raw = copy.deepcopy(raw)
    for text in overrides:
        key, value = parse_override(text)
        _set_path(raw, key, value)
    validate(raw, source=source, schema=schema)
    return raw


def load(path: str | Path, overrides: list[str] = (), schema: type[BaseModel] = ExperimentConfig) -> dict[str, Any]:
    """Read a config YAML, apply `--set` overrides, validate every grid combination against `schema`.

    Returns the raw dict (grids kept as `{grid_search: [...]}`) for Tune.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"config file {str(path)!r} does not exist")
    try:
        raw = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ValueError(f"config file {str(path)!r} is not valid YAML: {exc}") from None
    return from_dict(raw or {}, overrides, schema, source=str(path))
