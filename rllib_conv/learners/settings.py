"""`LearnerSettings`: what `MarginalPPOLearner` reads from RLlib's `learner_config_dict`, with the only defaults.

Kept apart from the learner (no torch, no Ray) so that configs can name these defaults
without importing RLlib.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass(frozen=True)
class LearnerSettings:
    """What `MarginalPPOLearner` reads from `learner_config_dict` (see the module docstring)."""

    # The regulariser's and the head penalty's weights: one for every replica, or one per replica of a packed ego
    # (replicas of different experiments, e.g. a lambda sweep, train in one algorithm).
    lam: float | tuple[float, ...] = 0.0
    freeze: tuple[str, ...] = ()
    adam_eps: float = 1e-5
    z_lr_scale: float = 1.0
    head_l2: float | tuple[float, ...] = 0.0
    # Module ID -> seed of the generator shuffling its minibatches (packed replicas shuffle
    # as each would alone); modules without one shuffle with NumPy's global RNG, as RLlib does.
    shuffle_seeds: dict[str, int] = field(default_factory=dict)
    # MEP (not in the paper): weight alpha of the population entropy, and the populations whose mean
    # policy it is taken of (name -> module IDs of the members' policies for one seat).
    population_entropy: float = 0.0
    populations: dict[str, list[str]] = field(default_factory=dict)
    # TrajeDi (not in the paper): weight of the populations' trajectory JSD, and the discount of its
    # local action likelihoods (`learners.trajectory_diversity`).
    trajectory_diversity: float = 0.0
    trajectory_discount: float = 0.5
    # The dtype of the learner's matrix products (`PPOSettings.precision`): "float32", or "bfloat16" under autocast.
    precision: str = "float32"

    def config_dict(self) -> dict[str, Any]:
        """The `learner_config_dict` that carries these settings to every learner."""
        return {
            **asdict(self),
            "freeze": list(self.freeze),
            "lam": _plain(self.lam),
            "head_l2": _plain(self.head_l2),
            "shuffle_seeds": dict(self.shuffle_seeds),
            "populations": {name: list(ids) for name, ids in self.populations.items()},
        }


def _plain(weight: float | tuple[float, ...]) -> float | list[float]:
    """A weight as a config dict holds it (a list for per-replica weights)."""
    return list(weight) if isinstance(weight, tuple) else weight


def replica_weights(weight: float | list[float] | tuple[float, ...], replicas: int) -> tuple[float, ...]:
    """`weight` as one float per replica (a single weight is every replica's); ValueError if a list has another length."""
    if isinstance(weight, (list, tuple)):
        if len(weight) != replicas:
            raise ValueError(f"{len(weight)} per-replica weights for {replicas} replicas")
        return tuple(float(w) for w in weight)
    return (float(weight),) * replicas
