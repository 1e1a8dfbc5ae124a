"""Builders shared by the RLlib-level tests: ego setups, learners without Ray, hand-made batches."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.evaluation.postprocessing import Postprocessing

from rllib_conv.envs.replicated_game import ReplicatedGame, replicated_env_config
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.training.algorithm import Replica, build_ppo_config
from rllib_conv.training.ego_setup import EgoSetup, resolve
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.replica_export import replica_module


def tiny_experiment(name: str, timesteps: int = 64) -> dict:
    """A bandit experiment small enough to train in seconds (1 symmetric context, 8 hidden units)."""
    return {
        "name": name,
        "population": "bandit-s1-hand",
        "model": {"hidden": 8},
        "ppo": {"rollout_per_partner": 16, "num_epochs": 1},
        "run": {"timesteps": timesteps},
    }


def bandit_setup(**overrides) -> EgoSetup:
    """The paper's bandit (2 symmetric contexts, 4 hand-designed partners) with `overrides`."""
    return resolve(ExperimentConfig(population="bandit-s2-hand", **overrides))


def build_learner(setup: EgoSetup | list[Replica]):
    """A built MarginalPPOLearner for `setup` (one replica) or packed `Replica`s, in this process (no Ray actors).

    Its module is a `StackedEgoMultiRLModule`: the weights under `stack`, one `HeadView`
    per head (`ego@<partner>#<r>`, `learner.module.head_ids()`), the fixed partners.
    """
    replicas = [Replica(setup)] if isinstance(setup, EgoSetup) else setup
    first = replicas[0].setup
    env = ReplicatedGame(replicated_env_config(first.population.env, first.env_config, [r.own_seed for r in replicas], 0))
    torch.manual_seed(0)
    return build_ppo_config(setup).build_learner(env=env)


def plain_ego(setup: EgoSetup):
    """The plain modules (`ConventionMultiRLModule`: `task`, `ego@<partner>`, partners) of a fresh learner's ego for `setup`,
    the form every trained ego is exported in."""
    return replica_module(build_learner(setup).module, 0, Replica(setup))


def task_weights(learner, replica: int = 0) -> dict[str, torch.Tensor]:
    """Replica `replica`'s task module weights in a built learner, under the plain `TaskModule`'s names."""
    return learner.module[STACK_ID].task_state(replica)


def head_weights(learner, head_id: str) -> dict[str, torch.Tensor]:
    """The weights of head view `head_id` (`ego@p#r`) in a built learner, under the plain `PartnerHeadModule`'s names."""
    view = learner.module[head_id]
    return learner.module[STACK_ID].head_state(view.replica, view.head)


def hand_batch(head_ids: list[str], rows: int = 6, num_contexts: int = 4, num_arms: int = 8, seed: int = 0) -> dict:
    """A hand-made PPO train batch per ego head: one-hot contexts, actions, advantages, targets."""
    rng = np.random.default_rng(seed)
    batch = {}
    for mid in head_ids:
        contexts = rng.integers(num_contexts, size=rows)
        actions = rng.integers(num_arms, size=rows)
        logits = rng.normal(size=(rows, num_arms)).astype(np.float32)
        logp = logits[np.arange(rows), actions] - np.log(np.exp(logits).sum(axis=1))
        batch[mid] = {
            Columns.OBS: {
                "observations": torch.as_tensor(np.eye(num_contexts, dtype=np.float32)[contexts]),
                "action_mask": torch.ones(rows, num_arms),
            },
            Columns.ACTIONS: torch.as_tensor(actions),
            Columns.ACTION_LOGP: torch.as_tensor(logp, dtype=torch.float32),
            Columns.ACTION_DIST_INPUTS: torch.as_tensor(logits),
            Postprocessing.ADVANTAGES: torch.as_tensor(rng.normal(size=rows), dtype=torch.float32),
            Postprocessing.VALUE_TARGETS: torch.as_tensor(rng.normal(size=rows), dtype=torch.float32),
        }
    return batch


def params_of(module) -> dict[str, torch.Tensor]:
    """A detached copy of a module's parameters by name."""
    return {k: v.detach().clone() for k, v in module.named_parameters()}


def digest(folder: Path) -> str:
    """One hash of every file's relative path and bytes under `folder`: equal iff nothing changed."""
    h = hashlib.sha256()
    for f in sorted(folder.rglob("*")):
        if f.is_file():
            h.update(str(f.relative_to(folder)).encode() + f.read_bytes())
    return h.hexdigest()
