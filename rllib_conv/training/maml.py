"""First-order MAML across training partners, on the single-network ego (task module + one head).

Replicas packed into one algorithm take their outer steps together, on the stacked
weights; the update is elementwise, so each replica moves as it would alone.

One outer step: take the next training partner; from the meta-weights theta run
`inner_iterations` ordinary PPO iterations with that partner only; then move theta by
`outer_step * (adapted - theta)` (Nichol et al. 2018's first-order update, the form the
paper cites). The network adapts to a new partner like BaselineAgg: fine-tune everything.
"""

from __future__ import annotations

from typing import Any

from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.training.weights import Weights, load_weights, push_learner_weights, snapshot

# Every replica's task module and single head: the stacked ego's weights, all of them.
META_MODULES = (STACK_ID,)


def outer_update(theta: Weights, adapted: Weights, step: float) -> Weights:
    """Return theta + step * (adapted - theta), tensor by tensor."""
    return {mid: {k: t + step * (adapted[mid][k] - t) for k, t in params.items()} for mid, params in theta.items()}


class MetaTrainer:
    """Runs MAML outer steps on an RLlib algorithm built for the `maml` method."""

    def __init__(
        self, algo: Any, partners: list[str], inner_iterations: int, outer_step: float, modules: tuple[str, ...] = META_MODULES
    ) -> None:
        self.algo, self.partners, self.modules = algo, partners, modules
        self.inner_iterations, self.outer_step = inner_iterations, outer_step
        self.outer_steps = 0

    def _focus(self, partner: str | None) -> None:
        self.algo.env_runner_group.foreach_env_runner(lambda runner: runner.config.policy_mapping_fn.focus(partner))

    def step(self) -> dict[str, Any]:
        """One outer step; returns the last inner iteration's RLlib result."""
        partner = self.partners[self.outer_steps % len(self.partners)]
        # One learner (or identical copies): the first result is the meta-weights.
        modules = self.modules
        theta = next(iter(self.algo.learner_group.foreach_learner(lambda learner: snapshot(learner.module, modules)))).get()
        self._focus(partner)
        for _ in range(self.inner_iterations):
            result = self.algo.train()
        step = self.outer_step
        self.algo.learner_group.foreach_learner(
            lambda learner: load_weights(learner.module, outer_update(theta, snapshot(learner.module, modules), step))
        )
        push_learner_weights(self.algo)
        self._focus(None)
        self.outer_steps += 1
        return result
