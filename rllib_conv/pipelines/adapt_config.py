"""`AdaptConfig`: the schema of `rllib-conv adapt` (adapting trained egos to new partners)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, NonNegativeInt, PositiveFloat, PositiveInt, confloat, model_validator

from rllib_conv.common.config_files import Strict
from rllib_conv.training.fine_tune_guard import DEFAULT_Z
from rllib_conv.training.settings import FolderName

Fraction = confloat(gt=0.0, lt=1.0)


class PosteriorSettings(Strict):
    """The convention posterior's priors and smoothing (`head_init: posterior`; `rllib_conv.training.convention_posterior`).

    `recombined`: prior of "the partner recombines known conventions situation by
    situation" against following one whole; `novel`: prior, per situation, of a convention
    none of the training partners follows; `epsilon`: the share of uniform play mixed into
    every training partner's model; `handover`: the posterior a whole known convention
    needs before the adapting head is started from its head (PPO fine-tunes it from there).
    """

    recombined: Fraction = 0.5  # type: ignore[valid-type]
    novel: Fraction = 0.1  # type: ignore[valid-type]
    epsilon: Fraction = 0.05  # type: ignore[valid-type]
    handover: Fraction = 0.95  # type: ignore[valid-type]


class AdaptConfig(Strict):
    """Adapting trained egos to new partners: keep the task module, a fresh head, lam 0.

    `runs` are trained-ego trial folders (or experiment folders: every trial in them).
    Partners are `split` of `population` (default: the population each run trained on),
    optionally only `partners`. `method: scratch` adapts a fresh network instead. The ego
    is evaluated before every update (`every` env steps) up to `steps`, `episodes` episodes
    each (and exactly on the bandit, where `episodes: 0` plays none and scores by the exact
    expectation alone: `mean_return` and `stderr` are then empty). Unset values take the
    paper's per-game adaptation settings (`rllib_conv.envs.defaults.ADAPT_DEFAULTS`); `ppo`
    overrides the run's PPO settings.
    `head_init: pick` (not in the paper; egos with one head per partner) first spends
    `pick_steps` env steps (default `every`) trying the fresh head and every training
    partner's head on the new partner, and adapts from the best (`rllib_conv.training.head_pick`).
    `head_init: posterior` (not in the paper; egos with one head per partner) adapts the
    fresh head as the paper does, and plays by a posterior over which training partner's
    convention the new partner follows, from the partner's moves (`posterior` settings;
    `rllib_conv.training.convention_posterior`). `guard: true` (not in the paper; with
    `head_init` fresh or posterior) evaluates the ego as it was before any update until the
    adapting one is measured better on its own training rollouts, by `guard_z` standard
    errors (`rllib_conv.training.fine_tune_guard`).
    """

    name: FolderName = "adapt"
    runs: list[str]
    population: str | None = None
    split: Literal["train", "test"] = "test"
    partners: list[str] | None = None
    method: Literal["scratch"] | None = None
    train_task: bool = True
    head_init: Literal["fresh", "pick", "posterior"] = "fresh"
    pick_steps: PositiveInt | None = None
    posterior: PosteriorSettings = Field(default_factory=PosteriorSettings)
    guard: bool = False
    guard_z: PositiveFloat = DEFAULT_Z
    every: PositiveInt | None = None
    steps: PositiveInt | None = None
    episodes: NonNegativeInt = 200
    ppo: dict[str, Any] = Field(default_factory=dict)
    seed: int = 0
    # Curves trained together as replicas of one algorithm (speed only: each trains as it would
    # alone, except in games of varying length, Hanabi, where a copy waits for the longest).
    max_pack: PositiveInt = 32

    @model_validator(mode="after")
    def _consistent(self) -> "AdaptConfig":
        if self.head_init != "fresh" and self.method == "scratch":
            raise ValueError(f"head_init {self.head_init!r} needs the trained ego's heads; method 'scratch' starts from a fresh network")
        if self.pick_steps is not None and self.head_init != "pick":
            raise ValueError(f"pick_steps is set but head_init is {self.head_init!r}; set head_init: pick to use it")
        if self.guard and self.head_init == "pick":
            raise ValueError("guard: true compares the adapting ego with the ego before any update, but head_init 'pick' replaces that ego after it; use head_init fresh or posterior")
        return self
