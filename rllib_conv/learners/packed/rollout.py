"""`Rollout`: sampled rows already laid out as RLlib's PPO learner connector lays out episodes, and its train batch.

RLlib's env runners hand the learner `MultiAgentEpisode`s, and its learner connector turns
them into the train batch: per module, each agent's episode (chunk) in the order the
episodes were returned becomes its n real rows plus one artificial bootstrap row (the
last observation again, reward 0, `loss_mask` False); values are computed on all of
them, GAE runs over them (`compute_value_targets`), advantages are standardized over all
rows of the module (bootstrap rows included) and `DropBootstrapRows` then drops the
bootstrap rows. On small games building and reading those episode objects is most of
the cost of an iteration.

A `Rollout` is what a sampler that skips the episode objects returns instead: the same
segments, one per (episode chunk, agent) with at least one move, appended per module in
the same order. `rollout_train_batch` makes the train batch from rollouts with RLlib's
own arithmetic, so it equals the connector's batch row for row
(`tests/training/test_rollout.py`). Only modules that learn (those with values) need
their rows.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.apis.value_function_api import ValueFunctionAPI
from ray.rllib.evaluation.postprocessing import Postprocessing
from ray.rllib.policy.sample_batch import MultiAgentBatch, SampleBatch
from ray.rllib.utils.postprocessing.value_predictions import compute_value_targets

from rllib_conv.envs.rllib_adapter import RLLIB_MASK_KEY as MASK_KEY
from rllib_conv.envs.rllib_adapter import RLLIB_OBS_KEY as OBS_KEY


@dataclass
class ModuleRows:
    """One module's segments, flat: every segment's observations (its n moves' and the last one), moves, and ends."""

    obs: list[np.ndarray] = field(default_factory=list)
    masks: list[np.ndarray] = field(default_factory=list)
    actions: list[int] = field(default_factory=list)
    logp: list[float] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    # Per segment: its number of moves n, whether the game ended it (terminated), or the
    # env truncated it or the sample ended first (truncated: its last value is a bootstrap).
    lengths: list[int] = field(default_factory=list)
    terminated: list[bool] = field(default_factory=list)
    truncated: list[bool] = field(default_factory=list)

    def add(
        self, obs: list[dict], actions: list[int], logp: list[float], rewards: list[float], terminated: bool, truncated: bool
    ) -> None:
        """Append one segment: `obs` holds n + 1 observations (`{"observations", "action_mask"}`) for n moves."""
        if len(obs) != len(actions) + 1 or not actions:
            raise ValueError(f"a segment needs n >= 1 moves and n + 1 observations; got {len(actions)} and {len(obs)}")
        self.obs.extend(o[OBS_KEY] for o in obs)
        self.masks.extend(o[MASK_KEY] for o in obs)
        self.actions.extend(actions)
        self.logp.extend(logp)
        self.rewards.extend(rewards)
        self.lengths.append(len(actions))
        self.terminated.append(bool(terminated))
        self.truncated.append(bool(truncated) or not terminated)


@dataclass
class Rollout:
    """What one `sample()` call played, per learning module; `env_steps`/`agent_steps` as RLlib counts them."""

    modules: dict[str, ModuleRows] = field(default_factory=dict)
    num_env_steps: int = 0
    num_agent_steps: int = 0

    def rows(self, module_id: str) -> ModuleRows:
        """The rows of `module_id` (created empty on first use)."""
        if module_id not in self.modules:
            self.modules[module_id] = ModuleRows()
        return self.modules[module_id]

    # What RLlib's sampling loop and learner ask of a sample's episodes.
    def env_steps(self) -> int:
        return self.num_env_steps

    def agent_steps(self) -> int:
        return self.num_agent_steps

    def __len__(self) -> int:
        return self.num_env_steps


def _module_columns(parts: list[ModuleRows]) -> dict[str, np.ndarray]:
    """One module's rows over several rollouts, with a bootstrap row after every segment (as the connector builds them)."""
    lengths = [n for p in parts for n in p.lengths]
    ends = np.cumsum([n + 1 for n in lengths]) - 1  # each segment's bootstrap row
    real = np.ones(ends[-1] + 1, dtype=bool)
    real[ends] = False
    rewards = np.zeros(len(real), dtype=np.float32)  # a bootstrap row earns 0
    rewards[real] = [r for p in parts for r in p.rewards]
    term = np.zeros(len(real), dtype=bool)
    trunc = np.zeros(len(real), dtype=bool)
    term[ends - 1] = [t for p in parts for t in p.terminated]
    trunc[ends - 1] = [t for p in parts for t in p.truncated]
    return {
        "obs": np.stack([o for p in parts for o in p.obs]).astype(np.float32, copy=False),
        "mask": np.stack([m for p in parts for m in p.masks]).astype(np.float32, copy=False),
        "actions": np.array([a for p in parts for a in p.actions], dtype=np.int64),
        "logp": np.array([lp for p in parts for lp in p.logp], dtype=np.float32),
        "rewards": rewards,
        "terminateds": term,
        "truncateds": trunc,
        "real": real,
    }


def segment_lengths(rollouts: list[Rollout]) -> dict[str, list[int]]:
    """Per module, the number of moves of each of its segments, in the order of its rows in `rollout_train_batch`."""
    out: dict[str, list[int]] = {}
    for r in rollouts:
        for mid, rows in r.modules.items():
            out.setdefault(mid, []).extend(rows.lengths)
    return out


def rollout_train_batch(rollouts: list[Rollout], multi_module: Any, gamma: float, lambda_: float) -> MultiAgentBatch:
    """The PPO train batch of `rollouts` (RLlib's GAE and standardization, bootstrap rows dropped), per learning module.

    Values come from each module's `compute_values` on all its rows, bootstrap rows
    included, as in RLlib's `GeneralAdvantageEstimation`; modules without values (fixed
    partners) are left out, as the learner would drop them.
    """
    ids = list(dict.fromkeys(mid for r in rollouts for mid in r.modules))
    batches = {}
    for mid in ids:
        module = multi_module[mid] if mid in multi_module else None
        if not isinstance(module, ValueFunctionAPI):
            continue
        cols = _module_columns([r.modules[mid] for r in rollouts if mid in r.modules])
        obs = {OBS_KEY: torch.from_numpy(cols["obs"]), MASK_KEY: torch.from_numpy(cols["mask"])}
        with torch.no_grad():
            values = module.compute_values({Columns.OBS: obs}).detach().cpu().numpy()
        targets = compute_value_targets(
            values=values,
            rewards=cols["rewards"],
            terminateds=cols["terminateds"],
            truncateds=cols["truncateds"],
            gamma=gamma,
            lambda_=lambda_,
        )
        advantages = targets - values
        advantages = (advantages - advantages.mean()) / max(1e-4, advantages.std())
        real = torch.from_numpy(cols["real"])
        batches[mid] = SampleBatch(
            {
                Columns.OBS: {k: v[real] for k, v in obs.items()},
                Columns.ACTIONS: torch.from_numpy(cols["actions"]),
                Columns.ACTION_LOGP: torch.from_numpy(cols["logp"]),
                Postprocessing.ADVANTAGES: torch.from_numpy(advantages[cols["real"]]),
                Postprocessing.VALUE_TARGETS: torch.from_numpy(targets[cols["real"]]),
            }
        )
    return MultiAgentBatch(batches, env_steps=sum(len(r) for r in rollouts))
