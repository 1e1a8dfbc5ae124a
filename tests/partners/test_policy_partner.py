"""A network partner that remembers its probabilities per state plays exactly as one that does not."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rllib_conv import envs, partners
from rllib_conv.partners.episodes import play_episodes
from rllib_conv.partners.trained import PolicyPartner


class CountingLogits:
    """Fixed random linear logits (masked), counting the rows it is asked for."""

    def __init__(self, obs_dim: int, actions: int, seed: int) -> None:
        self.weight = torch.randn(obs_dim, actions, generator=torch.Generator().manual_seed(seed))
        self.rows = 0

    def __call__(self, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        self.rows += len(obs)
        return (obs @ self.weight).masked_fill(mask == 0, -1e9)


@pytest.mark.parametrize("population", ["bandit-s2-hand", "blocks-perm"])
def test_a_memo_changes_no_action_and_saves_forward_passes(population: str) -> None:
    pop = partners.get(population)
    env = envs.make(pop.env, **pop.env_config)
    ego, other = env.possible_agents
    obs_dim, actions = env.observation_space(ego)["observation"].shape[0], env.action_space(ego).n
    scores, rows = {}, {}
    for memo in (False, True):
        logits = CountingLogits(obs_dim, actions, seed=1)
        seats = {ego: PolicyPartner("net", logits, seed=5, memo=memo), other: pop.partners[0].build()}
        scores[memo], rows[memo] = play_episodes(env, seats, 300, seed=9), logits.rows
    np.testing.assert_array_equal(scores[True], scores[False])
    assert len(np.unique(scores[False])) > 1  # the partner samples: the two runs could have differed
    assert rows[True] < rows[False] / 5, rows
