"""Games played side by side (`play_batched`) are the series `play_episodes` plays, one policy call per step."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import torch

from rllib_conv import envs, partners
from rllib_conv.partners.episodes import play_batched, play_episodes, score_episodes
from rllib_conv.partners.trained import PolicyPartner


class LinearLogits:
    """Fixed random linear logits (masked), counting its calls."""

    def __init__(self, obs_dim: int, actions: int, seed: int) -> None:
        self.weight = torch.randn(obs_dim, actions, generator=torch.Generator().manual_seed(seed))
        self.calls = 0

    def __call__(self, obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        self.calls += 1
        return (obs @ self.weight).masked_fill(mask == 0, -1e9)


def network_seats(game: str, greedy: bool, **env_config) -> tuple[functools.partial, dict[str, PolicyPartner]]:
    """An env factory for `game` and one random linear network in every seat."""
    make = functools.partial(envs.make_scored, game, **env_config)
    env = make()
    seats = {}
    for i, agent in enumerate(env.possible_agents):
        obs_dim = env.observation_space(agent)["observation"].shape[0]
        seats[agent] = PolicyPartner(f"net{i}", LinearLogits(obs_dim, env.action_space(agent).n, seed=i), greedy, seed=i)
    return make, seats


# AEC games (blocks, Hanabi) and parallel ones (the bandit, Level-Based Foraging with 3 seats).
GAMES = [("blocks", {}), ("hanabi", {}), ("bandit", {}), ("lbf", {"players": 3})]


@pytest.mark.parametrize(("game", "env_config"), GAMES)
@pytest.mark.parametrize("width", [1, 7, 64])
def test_greedy_seats_play_the_very_episodes_of_play_episodes(game: str, env_config: dict, width: int) -> None:
    make, seats = network_seats(game, greedy=True, **env_config)
    expected = play_episodes(make(), seats, 50, seed=3)
    got = play_batched(make, seats, 50, seed=3, width=width)
    np.testing.assert_array_equal(got, expected)
    assert len(np.unique(expected)) > 1 or game == "bandit"  # the episodes differ, so their order is checked


def test_one_policy_call_per_step_not_per_move() -> None:
    make, seats = network_seats("hanabi", greedy=True)
    play_episodes(make(), seats, 64, seed=0)
    one_by_one = sum(s.logits_fn.calls for s in seats.values())
    for s in seats.values():
        s.logits_fn.calls = 0
    play_batched(make, seats, 64, seed=0)
    batched = sum(s.logits_fn.calls for s in seats.values())
    assert batched < one_by_one / 20, (batched, one_by_one)


def test_sampling_seats_score_the_exact_return() -> None:
    """Sampled batched play of the bandit (an exact return exists) is unbiased: within 4 standard errors of it."""
    make, seats = network_seats("bandit", greedy=False)
    scores = play_batched(make, seats, 4000, seed=11)
    exact = envs.game("bandit").exact_return(seats, {})
    assert abs(scores.mean() - exact) < 4 * scores.std(ddof=1) / np.sqrt(len(scores)), (scores.mean(), exact)
    np.testing.assert_array_equal(play_batched(make, seats, 4000, seed=11), scores)  # and reproducible
    assert not np.array_equal(play_batched(make, seats, 4000, seed=12), scores)


class Echo(PolicyPartner):
    """A partner with state between moves: it repeats the other seat's last move where that is legal."""

    batchable = False

    def start_episode(self) -> None:
        self.last = None

    def observe_other(self, observation, action_mask, action, agent=None) -> None:
        self.last = action

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return self.last if self.last is not None and action_mask[self.last] else super().act(observation, action_mask)


def test_score_episodes_plays_stateful_partners_one_by_one() -> None:
    make, seats = network_seats("blocks", greedy=False)
    ego, other = list(seats)
    seats[other] = Echo("echo", seats[other].logits_fn, seed=4)
    np.testing.assert_array_equal(score_episodes(make, seats, 40, seed=2), play_episodes(make(), seats, 40, seed=2))
    with pytest.raises(ValueError, match="'echo'"):
        play_batched(make, seats, 40, seed=2)


@pytest.mark.parametrize("population", ["blocks-perm", "bandit-s2-hand", "lbf-heuristics", "hanabi-scripted"])
def test_scripted_partners_play_batched(population: str) -> None:
    """The built-in scripted partners keep no state: batched, the deterministic ones play the very episodes."""
    pop = partners.get(population)
    make = functools.partial(envs.make_scored, pop.env, **pop.env_config)
    env = make()
    entry = pop.partners[0].build()
    assert entry.batchable
    ego = next(a for a in env.possible_agents if a not in pop.partner_agents)
    obs_dim = env.observation_space(ego)["observation"].shape[0]
    seats = {
        a: entry if a != ego else PolicyPartner("net", LinearLogits(obs_dim, env.action_space(ego).n, 0), True)
        for a in env.possible_agents
    }
    batched, one_by_one = play_batched(make, seats, 30, seed=5), play_episodes(make(), seats, 30, seed=5)
    if entry.deterministic:
        np.testing.assert_array_equal(batched, one_by_one)
    assert batched.shape == (30,)


def test_an_empty_series_and_a_missing_seat() -> None:
    make, seats = network_seats("blocks", greedy=True)
    assert play_batched(make, seats, 0).shape == (0,)
    with pytest.raises(ValueError, match="player_1"):
        play_batched(make, {"player_0": seats["player_0"]}, 5)
