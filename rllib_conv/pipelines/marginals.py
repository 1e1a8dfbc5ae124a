"""How close each trained task module is to the true marginals (the paper's marginals figure).

States: every context on the bandit; on other games with an oracle, the ego's states
when it plays the oracle policy (uniform over optimal actions) with the training partners.
The distance is the L1 sum between the task module's distribution and the uniform
distribution over optimal actions, averaged over states with more than one optimal
action and at least one non-optimal legal action (`paper`), or over all states (`all`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rllib_conv import envs, partners
from rllib_conv.config import SINGLE_HEAD_METHODS
from rllib_conv.envs.oracles import oracle_for
from rllib_conv.modules.multi import AGG_HEAD_ID
from rllib_conv.partners.base import Partner
from rllib_conv.partners.play import play_episodes
from rllib_conv.partners.population import Population
from rllib_conv.pipelines.evaluate import bandit_states, load_module, marginal_distances

# Methods with a learned output to compare: the task module (modular), or the whole
# single network (BaselineAgg, MAML). BaselineModular's task logits are unused by its policy.
TASK_OUTPUT_METHODS = ("modular", "agg", "maml")


class OraclePartner(Partner):
    """Plays uniformly among the oracle's optimal actions (seeded); records what it saw."""

    kind = "oracle_policy"

    def __init__(self, name: str, env_name: str, env_config: dict[str, Any], seed: int = 0) -> None:
        super().__init__(name)
        self.oracle = oracle_for(env_name, env_config)
        self._rng = np.random.default_rng(seed)
        self.seen: list[tuple[np.ndarray, np.ndarray]] = []

    def seed(self, seed: int | None) -> None:
        self._rng = np.random.default_rng(seed)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        self.seen.append((np.array(observation), np.array(action_mask)))
        options = np.flatnonzero(self.oracle(observation[None])[0] * action_mask)
        return int(self._rng.choice(options))

    def params(self) -> dict[str, Any]:
        return {}


def marginal_states(population: Population, episodes: int = 200, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The ego's observations and masks on which the marginals are compared (see the module docstring)."""
    if population.env == "bandit":
        return bandit_states(population.env_config)
    env = envs.make(population.env, **population.env_config)
    ego_agent = next(a for a in env.possible_agents if a != population.partner_agent)
    oracle = OraclePartner("oracle", population.env, population.env_config, seed)
    for i, entry in enumerate(population.entries("train")):
        play_episodes(env, {ego_agent: oracle, population.partner_agent: entry.build()}, episodes, seed + 1000 * i)
    obs = np.stack([o for o, _ in oracle.seen]).astype(np.float32)
    mask = np.stack([m for _, m in oracle.seen]).astype(np.int8)
    return obs, mask


def marginal_report(trials: list[Path], episodes: int = 200, seed: int = 0) -> pd.DataFrame:
    """One row per trained ego with a task output: its task module's distance to the true marginals."""
    from rllib_conv.pipelines.checkpoints import last_checkpoint
    from rllib_conv.pipelines.train import trial_config

    rows, states = [], {}
    for trial in trials:
        exp = trial_config(trial)
        if exp.method not in TASK_OUTPUT_METHODS:
            continue
        pop = partners.get(exp.population)
        key = (pop.name, episodes, seed)
        if key not in states:
            states[key] = marginal_states(pop, episodes, seed)
        obs, mask = states[key]
        module = load_module(last_checkpoint(trial))
        d = marginal_distances(module, pop.env, pop.env_config, obs, mask, AGG_HEAD_ID if exp.method in SINGLE_HEAD_METHODS else None)
        rows.append(
            {
                "run": str(trial),
                "env": pop.env,
                "env_config": str(pop.env_config),
                "population": pop.name,
                "method": exp.method,
                "lam": exp.lam,
                "z_dim": exp.model.z_dim or exp.model.hidden,
                "seed": exp.seed,
                "distance": d["paper"],
                "distance_all_states": d["all"],
                "states": len(obs),
            }
        )
    return pd.DataFrame(rows)
