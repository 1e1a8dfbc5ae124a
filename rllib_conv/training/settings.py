"""Typed settings shared by every training schema: network sizes, PPO, the run, MAML; and the field types they use.

The schemas that combine them live beside what they configure: `experiment.ExperimentConfig`
(one ego) here, and the pipelines' own (adaptation, zero-shot, self-play) in
`rllib_conv.pipelines`. Unset game-dependent values (None) take the paper's value for
the game (`rllib_conv.envs.defaults`).
"""

from __future__ import annotations

import warnings
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    Field,
    NonNegativeFloat,
    NonNegativeInt,
    PositiveFloat,
    PositiveInt,
    ValidationError,
    ValidatorFunctionWrapHandler,
    WrapValidator,
    model_validator,
)

from rllib_conv.common.config_files import Strict
from rllib_conv.envs.registry import factory as env_factory
from rllib_conv.learners.settings import LearnerSettings


def _folder_name(v: str) -> str:
    if not v or any(c in v for c in '/\\<>:"|?* '):
        raise ValueError(f'must be a non-empty folder name without spaces or /\\<>:"|?*, got {v!r}')
    return v


def _registered_env(v: str) -> str:
    env_factory(v)  # ValueError naming the registered envs
    return v


def _schedule_starts_at_zero(v: Any) -> Any:
    if isinstance(v, list) and (not v or v[0][0] != 0 or any(a[0] >= b[0] for a, b in zip(v, v[1:]))):
        raise ValueError("a schedule must be [[0, value], [step, value], ...] with increasing steps")
    return v


def _entropy_in_words(v: Any, handler: ValidatorFunctionWrapHandler) -> Any:
    """A constant or a schedule; anything else is said in words, not as the types pydantic tried."""
    try:
        return handler(v)
    except ValidationError:
        raise ValueError(
            f"expected a number >= 0, or a schedule [[0, value], [step, value], ...] of whole steps >= 0 and values >= 0; got {v!r}"
        ) from None


REMOVED_BATCHED_SAMPLING = (
    "run.batched_sampling is ignored: it was removed, egos and self-play pairs always sample with "
    "BatchedEnvRunner (the same train batches as RLlib's episode path); drop the key"
)

FolderName = Annotated[str, AfterValidator(_folder_name)]
EnvName = Annotated[str, AfterValidator(_registered_env)]
# A constant, or a piecewise-linear schedule [[env_step, value], ...] starting at step 0.
EntropyCoeff = Annotated[
    NonNegativeFloat | list[tuple[NonNegativeInt, NonNegativeFloat]],
    WrapValidator(_entropy_in_words),
    AfterValidator(_schedule_starts_at_zero),
]


class ModelSettings(Strict):
    """Network sizes: every layer of both modules has `hidden` units; z has `z_dim` (default hidden); the heads' layout."""

    hidden: PositiveInt | None = None
    z_dim: PositiveInt | None = None
    heads: Literal["team", "seat"] = Field(
        "team",
        description="in a game of more than two seats, the modular ego's heads: one per team of training partners "
        "(team: P**(k-1) heads), or one per partner seat and partner whose logits and values add (seat: P*(k-1) heads, "
        "and a new team's head starts as the sum of fresh seat heads); the same in a game of two seats",
    )


class PPOSettings(Strict):
    """PPO hyperparameters (defaults: the paper's code, Stable-Baselines3 PPO)."""

    lr: PositiveFloat = 3e-4
    gamma: float = Field(0.99, ge=0.0, le=1.0)
    gae_lambda: float = Field(0.95, ge=0.0, le=1.0)
    clip_param: PositiveFloat = 0.2
    entropy_coeff: EntropyCoeff = 0.0
    vf_loss_coeff: float = Field(0.5, ge=0.0)
    grad_clip: PositiveFloat | None = 0.5
    adam_eps: PositiveFloat = LearnerSettings.adam_eps
    rollout_per_partner: PositiveInt | None = None
    minibatch_size: PositiveInt | None = None
    num_epochs: PositiveInt | None = None
    # Not in the paper: "bfloat16" runs the learner's forward and loss under torch's autocast (matrix products in
    # bfloat16; weights, gradients' accumulation, Adam and the loss's reductions stay float32). ~1.5x a Hanabi update on
    # a CPU with AMX (benchmarks/learner_update.py --precision); slower on CPUs without bfloat16 units. Sampling stays float32.
    precision: Literal["float32", "bfloat16"] = LearnerSettings.precision

    def learner_settings(self, **settings: Any) -> LearnerSettings:
        """The learner's settings for these PPO hyperparameters (Adam's epsilon, precision), plus `settings`."""
        return LearnerSettings(adam_eps=self.adam_eps, precision=self.precision, **settings)


class RunSettings(Strict):
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

    @model_validator(mode="before")
    @classmethod
    def _removed_keys(cls, data: Any) -> Any:
        # Trial folders written before 2026-12-05 carry `batched_sampling` in their config.yaml;
        # they must still load. Sampling is always batched now (the same train batches as RLlib's
        # episode path, `tests/training/test_batched_env_runner.py`), so the key changes nothing.
        if isinstance(data, dict) and "batched_sampling" in data:
            warnings.warn(REMOVED_BATCHED_SAMPLING, FutureWarning, stacklevel=2)
            data = {k: v for k, v in data.items() if k != "batched_sampling"}
        return data


class MAMLSettings(Strict):
    """First-order MAML across training partners (the paper's Table 5 values).

    Each outer step takes the next training partner, runs `inner_iterations` PPO updates
    (learning rate `ppo.lr`, the paper's inner lr 3e-4) from the meta-weights theta, and
    moves theta by `outer_step * (adapted - theta)`.
    """

    inner_iterations: PositiveInt = 4
    outer_step: float = Field(0.25, gt=0.0, le=1.0)


class MappingSettings(Strict):
    """Which training partner each episode is played with: the choice behind the agent -> module mapping.

    `round_robin` (default, the paper's): partners in turn. `weighted`: each episode's
    partner drawn with `weights` (partner name -> weight; partners left out get 0), from a
    generator seeded from the run's seed. `function`: the user's
    `function(episode, partners, rng) -> partner name`, named by import path
    (`package.module:function`), importable where the env runners run.
    """

    kind: Literal["round_robin", "weighted", "function"] = "round_robin"
    weights: dict[str, NonNegativeFloat] | None = None
    function: str | None = None

    @model_validator(mode="after")
    def _consistent(self) -> "MappingSettings":
        if (self.kind == "weighted") != (self.weights is not None):
            raise ValueError("mapping.weights is for kind 'weighted', which needs it (partner name -> weight)")
        if self.weights is not None and sum(self.weights.values()) <= 0:
            raise ValueError(f"mapping.weights must give some partner a positive weight; got {self.weights}")
        if (self.kind == "function") != (self.function is not None):
            raise ValueError("mapping.function is for kind 'function', which needs it ('package.module:function')")
        return self
