"""How close a task module is to the true marginals (the paper's marginals figure): the states and the distance.

States: every state where the game lists them (`GameRecord.states`: the bandit's contexts);
on other games with an oracle, the ego's states when it plays the oracle policy (uniform
over optimal actions) with the training partners.
The distance is the L1 sum between the task module's distribution and the uniform
distribution over optimal actions, averaged over states with more than one optimal
action and at least one non-optimal legal action (`paper`), or over all states (`all`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv import envs
from rllib_conv.common.seeds import series_seed
from rllib_conv.envs.oracles import canonical_actions, oracle_for
from rllib_conv.modules.multi import ConventionMultiRLModule
from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import play_episodes
from rllib_conv.partners.population import Population
from rllib_conv.training.evaluate import head_probs, task_probs


def merge_actions(values: np.ndarray, canon: np.ndarray) -> np.ndarray:
    """Sum `values` [B, A] onto each row's canonical actions (`canon` [B, A] of action indices)."""
    out = np.zeros_like(values, dtype=np.float64)
    rows = np.repeat(np.arange(len(values)), values.shape[1])
    np.add.at(out, (rows, canon.ravel()), values.ravel())
    return out


def optimal_actions(env_name: str, env_config: dict[str, Any], obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """[B, A] bool: which canonical actions are optimal in each state (the game's oracle, legal actions only)."""
    canon = canonical_actions(env_name, obs, mask.shape[1])
    return merge_actions(oracle_for(env_name, env_config)(obs) * mask, canon) > 0


def marginal_distances(
    module: ConventionMultiRLModule,
    env_name: str,
    env_config: dict[str, Any],
    obs: np.ndarray,
    mask: np.ndarray,
    head_id: str | None = None,
) -> dict[str, float]:
    """L1 distance between the task module's distribution and the true marginals on `obs`.

    With `head_id` the policy of that head is compared instead (single-network methods,
    whose whole policy is their estimate of the marginals). `paper`: averaged over states
    with more than one optimal action and at least one non-optimal legal action (the
    paper's marginals figure); `all`: over every state.
    """
    canon = canonical_actions(env_name, obs, mask.shape[1])
    optimal = optimal_actions(env_name, env_config, obs, mask)
    truth = optimal / optimal.sum(axis=1, keepdims=True)
    probs = task_probs(module, obs, mask) if head_id is None else head_probs(module, head_id, obs, mask)
    dist = np.abs(merge_actions(probs, canon) - truth).sum(axis=1)
    n_opt = optimal.sum(axis=1)
    distinct = (merge_actions(mask.astype(float), canon) > 0).sum(axis=1)
    ambiguous = (n_opt > 1) & (n_opt < distinct)
    return {"paper": float(dist[ambiguous].mean()) if ambiguous.any() else float("nan"), "all": float(dist.mean())}


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
    listed = envs.game(population.env).states
    if listed is not None:
        return listed(population.env_config)
    env = envs.make(population.env, **population.env_config)
    ego_agent = population.ego_agent(env.possible_agents)
    oracle = OraclePartner("oracle", population.env, population.env_config, seed)
    for i, entry in enumerate(population.entries("train")):
        play_episodes(env, {ego_agent: oracle, population.partner_agent: entry.build()}, episodes, series_seed(seed, i))
    obs = np.stack([o for o, _ in oracle.seen]).astype(np.float32)
    mask = np.stack([m for _, m in oracle.seen]).astype(np.int8)
    return obs, mask
