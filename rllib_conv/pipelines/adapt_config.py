"""`AdaptConfig`: the schema of `rllib-conv adapt` (adapting trained egos to new partners)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import (
    Field,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    ValidationError,
    confloat,
    field_validator,
    model_validator,
)

from rllib_conv.adaptation.fine_tune_guard import DEFAULT_Z
from rllib_conv.common.adapters import FRESH, GUARD, PICK, StartName, adapter
from rllib_conv.common.config_files import Strict, describe
from rllib_conv.training.settings import FolderName, PPOSettings

Fraction = confloat(gt=0.0, lt=1.0)


class PosteriorSettings(Strict):
    """The convention posterior's priors and smoothing (`head_init: posterior`; `rllib_conv.adaptation.convention_posterior`).

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
    paper's per-game adaptation settings (the game record's `adaptation`, `rllib_conv.envs.game.GameRecord`); `ppo`
    overrides the run's PPO settings.
    `head_init: pick` (not in the paper; egos with one head per partner) first spends
    `pick_steps` env steps (default `every`) trying the fresh head and every training
    partner's head on the new partner, and adapts from the best (`rllib_conv.adaptation.head_pick`).
    `head_init: posterior` (not in the paper; egos with one head per partner) adapts the
    fresh head as the paper does, and plays by a posterior over which training partner's
    convention the new partner follows, from the partner's moves (`posterior` settings;
    `rllib_conv.adaptation.convention_posterior`). `guard: true` (not in the paper; with
    `head_init` fresh or posterior) evaluates the ego as it was before any update until the
    adapting one is measured better on its own training rollouts, by `guard_z` standard
    errors (`rllib_conv.adaptation.fine_tune_guard`). `head_init` lookup, counts-planner and
    prior-planner (not in the paper) are the posterior's information-parity controls
    (`rllib_conv.common.adapters.CONTROLS`): they play by the new partner's moves as the ego's
    seat saw them (or, prior-planner, by the training partners alone), never by PPO's head.
    `head_init: plastic` (not in the paper; Barrett & Stone's PLASTIC) keeps a belief over which
    training partner sits in each partner seat, from each seat's moves as the ego's own
    observation shows them, and plays the trained ego's head for the most probable team
    (`rllib_conv.adaptation.plastic`; `posterior.epsilon` smooths its models). In a game of more
    than two seats a partner is a team (`partners`: `H3+H4`, or `H3` in every seat; default every
    team of the split); fresh (guarded or not), plastic and known-seats adapt there, the other starts are refused.
    `head_init: known-seats` (not in the paper; egos trained with `model.heads: seat`) starts each
    member of the team the ego trained with in that seat from its trained seat head, each new
    member from a fresh one, and adapts them all as fresh does.
    """

    name: FolderName = Field("adapt", description="name of the output CSV and Tune experiment")
    runs: list[str] = Field(description="trained-ego trial folders or experiment folders")
    population: str | None = Field(None, description="population of the new partners (default: the one each run trained on)")
    split: Literal["train", "test"] = Field("test", description="which partners of the population to adapt to")
    partners: list[str] | None = Field(
        None,
        description="adapt to these partners only (names: rllib-conv partners show POP); with several partner seats teams, "
        "one name per seat joined by '+' (H3+H4) or one name for every seat; default: the split (every team of it)",
    )
    method: Literal["scratch"] | None = Field(None, description="scratch: adapt a fresh network instead (learning from scratch)")
    train_task: bool = Field(True, description="train the task module while adapting (false keeps it frozen)")
    head_init: StartName = Field(
        FRESH,
        description="pick: first try the fresh head and every training partner's head on the new partner, adapt from the best; "
        "posterior: adapt the fresh head and play by a posterior over which training partner's convention the new partner follows; "
        "lookup, counts-planner, prior-planner: the posterior's information-parity controls (docs/adapting.md); "
        "plastic: a belief over the training partners' types per partner seat, playing the head of the most probable team; "
        "known-seats: a seat-head ego keeps the seat heads of the team's known members, a fresh one per new member "
        "(all not in the paper)",
    )
    pick_steps: PositiveInt | None = Field(None, description="env steps spent picking the head (default: one update's worth)")
    posterior: PosteriorSettings = Field(
        default_factory=PosteriorSettings,
        description="--head-init posterior's priors, e.g. --set posterior.recombined=0.5 posterior.novel=0.1 posterior.epsilon=0.05 posterior.handover=0.95",
    )
    guard: bool = Field(
        False,
        description="evaluate the ego as it was before any update until the adapting one is measured better on its own rollouts "
        "(with --head-init fresh or posterior; not in the paper)",
    )
    guard_z: PositiveFloat = Field(
        DEFAULT_Z, description="--guard's margin: standard errors by which the adapting ego's mean return must beat the prior's"
    )
    every: PositiveInt | None = Field(
        None, description="env steps between evaluations, one PPO update each (default: the game's adaptation protocol)"
    )
    steps: PositiveInt | None = Field(None, description="env steps of adaptation (default: the game's adaptation protocol)")
    episodes: NonNegativeInt | None = Field(
        None,
        description="episodes per evaluation (default: the game's adaptation protocol, 200 for most; "
        "0 on the bandit: scored by the exact expectation alone)",
    )
    ppo: dict[str, Any] = Field(
        default_factory=dict, description="PPO settings replacing the run's, e.g. --set ppo.lr=1e-4 or ppo.num_epochs=10"
    )
    seed: int = Field(0, description="seed of the evaluation episodes")
    # Curves trained together as replicas of one algorithm (speed only: each trains as it would
    # alone, except in games of varying length, Hanabi, where a copy waits for the longest).
    max_pack: PositiveInt = Field(
        32, description="curves trained together in one algorithm, for speed (each trains as it would alone)"
    )

    @field_validator("ppo")
    @classmethod
    def _ppo_settings(cls, ppo: dict[str, Any]) -> dict[str, Any]:
        # Checked here, before any training, against the settings it replaces (a partial override: the rest are the run's).
        try:
            PPOSettings.model_validate(ppo)
        except ValidationError as exc:
            raise ValueError(describe(exc)) from None
        return ppo

    @model_validator(mode="after")
    def _consistent(self) -> "AdaptConfig":
        if adapter(self.head_init).needs_partner_heads and self.method == "scratch":
            raise ValueError(
                f"head_init {self.head_init!r} needs the trained ego's heads; method 'scratch' starts from a fresh network"
            )
        if self.pick_steps is not None and self.head_init != PICK:
            raise ValueError(f"pick_steps is set but head_init is {self.head_init!r}; set head_init: pick to use it")
        if self.guard and self.head_init not in adapter(GUARD).guards:
            raise ValueError(
                "guard: true compares the adapting ego with the ego before any update, but "
                + (
                    "head_init 'pick' replaces that ego after it"
                    if self.head_init == PICK
                    else f"head_init {self.head_init!r} never plays the adapting ego"
                )
                + f"; use head_init {' or '.join(adapter(GUARD).guards)}"
            )
        return self
