"""`LearnerSettings`: what `MarginalPPOLearner` reads from RLlib's `learner_config_dict`, with the only defaults.

Kept apart from the learner (no torch, no Ray) so that configs can name these defaults
without importing RLlib.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any


@dataclass(frozen=True)
class LearnerSettings:
    """What `MarginalPPOLearner` reads from `learner_config_dict` (see the module docstring)."""

    lam: float = 0.0
    freeze: tuple[str, ...] = ()
    adam_eps: float = 1e-5
    z_lr_scale: float = 1.0
    head_l2: float = 0.0

    def config_dict(self) -> dict[str, Any]:
        """The `learner_config_dict` that carries these settings to every learner."""
        return {**asdict(self), "freeze": list(self.freeze)}
