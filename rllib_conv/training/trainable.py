"""`AlgorithmTrainable`: the one Tune Trainable base class of every pipeline (train, adapt, zero-shot, self-play).

It holds an RLlib algorithm in `self.algo`, runs torch on one thread, saves the algorithm
and the RNG state (`rng_state`) into sealed checkpoints and verifies them before
restoring, stops the algorithm when the trial ends, and asks Ray for what the trial's
`run` settings say (`tuning.trial_resources`). Subclasses build `self.algo` in `setup`
(after calling this class's), implement `step`, and write state beyond the algorithm's in
`save_extra` / read it in `load_extra`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch
from ray import tune
from ray.tune.execution.placement_groups import PlacementGroupFactory

from rllib_conv.common.sealed import seal, verify
from rllib_conv.training import rng_state
from rllib_conv.training.tuning import trial_resources


class AlgorithmTrainable(tune.Trainable):
    """A Tune trial driving one RLlib algorithm (`self.algo`); see the module docstring."""

    algo: Any

    def setup(self, config: dict[str, Any]) -> None:
        # The learner slows down 10-40x when torch threads compete with env runners.
        torch.set_num_threads(1)

    def save_extra(self, checkpoint_dir: Path) -> None:
        """Write state beyond the algorithm's into the checkpoint (before it is sealed)."""

    def load_extra(self, checkpoint_dir: Path) -> None:
        """Read what `save_extra` wrote."""

    def save_checkpoint(self, checkpoint_dir: str) -> None:
        self.algo.save_to_path(checkpoint_dir)
        rng_state.save(self.algo, checkpoint_dir)
        self.save_extra(Path(checkpoint_dir))
        seal(checkpoint_dir)

    def load_checkpoint(self, checkpoint: str) -> None:
        verify(checkpoint)
        self.algo.restore_from_path(checkpoint)
        rng_state.load(self.algo, checkpoint)
        self.load_extra(Path(checkpoint))

    def cleanup(self) -> None:
        self.algo.stop()

    @classmethod
    def default_resource_request(cls, config: dict[str, Any]) -> PlacementGroupFactory:
        return trial_resources(config.get("run") if isinstance(config.get("run"), dict) else None)
