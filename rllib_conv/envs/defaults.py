"""The shapes of a game's paper settings: training, adaptation and zero-shot protocols.

Each game's values sit in its record (`envs/<game>/record.py`, from the paper's Tables 2-4
and its released code; `docs/differences.md` lists where we differ). Configs leave these
unset and take them from their game's record; a game without them gets `FALLBACK_DEFAULTS`
(and, for adaptation and zero-shot, settings derived from its rollout): ask
`envs.game(name).training_defaults()`, `.adapt_defaults(...)`, `.zeroshot_defaults(...)`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class TrainingDefaults:
    """Layer size, rollout steps per partner, minibatch, epochs, training env steps."""

    hidden: int
    rollout_per_partner: int
    minibatch_size: int
    num_epochs: int
    timesteps: int

    def as_dict(self) -> dict[str, int]:
        """The settings by name."""
        return asdict(self)


@dataclass(frozen=True)
class AdaptDefaults:
    """The adaptation protocol: evaluate every `every` env steps up to `steps`, `episodes`
    episodes each; one PPO update of `minibatch_size` x `num_epochs` per `every` steps (None:
    the trained ego's)."""

    every: int
    steps: int
    minibatch_size: int | None = None
    num_epochs: int | None = None
    episodes: int = 200


@dataclass(frozen=True)
class ZeroShotDefaults:
    """Zero-shot budgets: step 1 trains the test heads on the old task until they have
    converged; step 2 re-trains the task module on the new task."""

    head_steps: int
    task_steps: int


FALLBACK_DEFAULTS = TrainingDefaults(hidden=64, rollout_per_partner=256, minibatch_size=64, num_epochs=10, timesteps=100_000)
