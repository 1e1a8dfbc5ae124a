"""Module weights moved by hand, outside a PPO update: snapshots, in-place loads, and pushing them to env runners."""

from __future__ import annotations

from typing import Any

import torch
from ray.rllib.core import COMPONENT_LEARNER, COMPONENT_RL_MODULE

Weights = dict[str, dict[str, torch.Tensor]]  # module ID -> state dict


def snapshot(module: Any, module_ids: tuple[str, ...]) -> Weights:
    """A detached copy of the weights of `module_ids` in a MultiRLModule."""
    return {mid: {k: v.detach().clone() for k, v in module[mid].state_dict().items()} for mid in module_ids}


def load_weights(module: Any, weights: Weights) -> None:
    """Write `weights` into the MultiRLModule's sub-modules in place (optimizers keep their tensors)."""
    with torch.no_grad():
        for mid, params in weights.items():
            for k, v in module[mid].state_dict().items():
                v.copy_(params[k])


def push_learner_weights(algo: Any) -> None:
    """Send the learner's module weights to every env runner, local and remote (as PPO does after an update)."""
    state = algo.learner_group.get_state(components=f"{COMPONENT_LEARNER}/{COMPONENT_RL_MODULE}", inference_only=True)
    # No weights sequence number: env runners skip states whose number they have seen, and
    # weights changed outside an update (MAML's outer step, a reset layer) keep the old one.
    module_state = {COMPONENT_RL_MODULE: state[COMPONENT_LEARNER][COMPONENT_RL_MODULE]}
    algo.env_runner_group.sync_env_runner_states(config=algo.config, rl_module_state=module_state)


def learner_module(algo: Any) -> Any:
    """The learner's MultiRLModule of an algorithm with a local learner (every module, value towers included)."""
    learner = getattr(algo.learner_group, "_learner", None)
    if learner is None:
        raise RuntimeError(
            "the algorithm has remote learners; its module is reachable through learner_group.foreach_learner only"
        )
    return learner.module
