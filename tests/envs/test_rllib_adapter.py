"""PettingZoo -> RLlib adapter: Dict masked observations, turn order, rewards, user envs, Tune registration."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium import spaces
from pettingzoo import AECEnv, ParallelEnv
from pettingzoo.utils import AgentSelector
from ray.rllib.utils.pre_checks.env import check_multiagent_environments
from ray.tune.registry import ENV_CREATOR, _global_registry

from rllib_conv import envs
from rllib_conv.envs.blocks import PASS
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv, to_rllib


def adapted(name: str, **config) -> PettingZooMultiAgentEnv:
    return PettingZooMultiAgentEnv(envs.make(name, **config))


@pytest.mark.parametrize(("name", "config"), [("bandit", {"symmetric": 2}), ("blocks", {})])
def test_rllib_checker_accepts_adapted_games(name: str, config: dict) -> None:
    check_multiagent_environments(adapted(name, **config))


@pytest.mark.parametrize("name", ["bandit", "blocks", "hanabi"])
def test_a_restored_rng_state_continues_the_games_stream_in_a_fresh_env(name: str) -> None:
    # A resumed trial builds fresh envs and restores their RNG states before their first reset; Hanabi makes
    # its generator only at its first reset, which once made every resumed Hanabi trial fail.
    first = adapted(name)
    first.reset(seed=3)
    state = first.get_rng_state()
    expected = first.reset(seed=None)[0]
    fresh = adapted(name)
    fresh.set_rng_state(state)
    got = fresh.reset(seed=99)[0]  # the seed RLlib passes is ignored: the stream continues
    assert got.keys() == expected.keys()
    for agent in got:
        for key in got[agent]:
            np.testing.assert_array_equal(got[agent][key], expected[agent][key])


def test_bandit_observations_are_rllib_dicts() -> None:
    env = adapted("bandit", symmetric=2)
    obs, infos = env.reset(seed=3)
    assert set(obs) == {"player_0", "player_1"}
    for agent, o in obs.items():
        assert set(o) == {"observations", "action_mask"}
        assert o["observations"].dtype == np.float32 and o["action_mask"].dtype == np.float32
        assert o["action_mask"].tolist() == [1.0] * 8
        assert env.observation_spaces[agent].contains(o)
    c = infos["player_0"]["context"]
    obs, rewards, terms, truncs, _ = env.step({"player_0": c, "player_1": c})
    assert rewards == {"player_0": 1.0, "player_1": 1.0}
    assert terms["__all__"] and not truncs["__all__"]


def test_blocks_turns_and_final_reward_reach_both_players() -> None:
    env = adapted("blocks")
    obs, _ = env.reset(seed=0)
    goal = env.env.goal
    assert list(obs) == ["player_0"]
    moves = [0, 3, PASS, PASS, PASS, PASS]
    env.env.goal = (0, 3)
    totals = {"player_0": 0.0, "player_1": 0.0}
    for i, a in enumerate(moves):
        mover = "player_0" if i % 2 == 0 else "player_1"
        obs, rewards, terms, truncs, _ = env.step({mover: a})
        for agent, r in rewards.items():
            totals[agent] += r
        if i < len(moves) - 1:
            assert list(obs) == ["player_1" if mover == "player_0" else "player_0"] and not terms["__all__"]
    assert set(obs) == {"player_0", "player_1"} and terms["__all__"]
    assert terms["player_0"] and terms["player_1"]
    assert totals == {"player_0": 20.0, "player_1": 20.0}
    assert goal in [(r, b) for r in range(4) for b in range(4) if r != b]


def test_wrong_mover_is_an_error() -> None:
    env = adapted("blocks")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="it is player_0's turn"):
        env.step({"player_1": 0})


class _BoxParallel(ParallelEnv):
    """A user game with plain Box observations and no action mask."""

    metadata = {"name": "box_v0"}
    possible_agents = ["a", "b"]

    def observation_space(self, agent):
        return spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float64)

    def action_space(self, agent):
        return spaces.Discrete(2)

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        return {a: np.zeros(3) for a in self.agents}, {a: {} for a in self.agents}

    def step(self, actions):
        self.agents = []
        r = float(actions["a"] == actions["b"])
        return (
            {a: np.ones(3) for a in "ab"},
            {a: r for a in "ab"},
            {a: True for a in "ab"},
            {a: False for a in "ab"},
            {a: {} for a in "ab"},
        )


class _DiscreteAEC(AECEnv):
    """A user AEC game with Discrete observations and the mask in `info`."""

    metadata = {"name": "disc_v0"}
    possible_agents = ["x", "y"]

    def observation_space(self, agent):
        return spaces.Discrete(3)

    def action_space(self, agent):
        return spaces.Discrete(3)

    def observe(self, agent):
        return self.t

    def reset(self, seed=None, options=None):
        self.agents = list(self.possible_agents)
        self.t = 0
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos = {a: {"action_mask": np.array([1, 0, 1], dtype=np.int8)} for a in self.agents}
        self._selector = AgentSelector(self.agents)
        self.agent_selection = self._selector.reset()

    def step(self, action):
        if self.terminations[self.agent_selection]:
            self._was_dead_step(action)
            return
        self._cumulative_rewards[self.agent_selection] = 0.0
        self.t += 1
        self._clear_rewards()
        if self.t == 2:
            self.rewards = {a: 1.0 for a in self.agents}
            self.terminations = {a: True for a in self.agents}
        self._accumulate_rewards()
        self.agent_selection = self._selector.next()


def test_user_envs_get_masks_and_flat_float_observations() -> None:
    envs.register("test-box", _BoxParallel, overwrite=True)
    env = adapted("test-box")
    obs, _ = env.reset()
    assert obs["a"]["action_mask"].tolist() == [1.0, 1.0] and obs["a"]["observations"].dtype == np.float32
    check_multiagent_environments(env)

    envs.register("test-disc", _DiscreteAEC, overwrite=True)
    env = adapted("test-disc")
    obs, _ = env.reset()
    assert obs["x"]["observations"].tolist() == [1.0, 0.0, 0.0]  # one-hot of Discrete obs 0
    assert obs["x"]["action_mask"].tolist() == [1.0, 0.0, 1.0]  # taken from info
    obs, rew, terms, _, _ = env.step({"x": 0})
    assert list(obs) == ["y"] and obs["y"]["observations"].tolist() == [0.0, 1.0, 0.0]
    obs, rew, terms, _, _ = env.step({"y": 2})
    assert terms["__all__"] and rew == {"x": 1.0, "y": 1.0}


def test_register_rejects_duplicates_and_non_callables() -> None:
    with pytest.raises(ValueError, match="already registered"):
        envs.register("bandit", _BoxParallel)
    with pytest.raises(ValueError, match="must be callable"):
        envs.register("x", 3)


def test_to_rllib_registers_a_tune_env() -> None:
    env_id = to_rllib("bandit")
    assert env_id == "rllib_conv/bandit"
    assert _global_registry.contains(ENV_CREATOR, env_id)
    env = _global_registry.get(ENV_CREATOR, env_id)({"symmetric": 3})
    assert isinstance(env, PettingZooMultiAgentEnv) and env.env.num_contexts == 4
    with pytest.raises(ValueError, match="unknown env 'nope'"):
        to_rllib("nope")
