"""The collaborative contextual bandit: PettingZoo API, seeding, payoffs, tasks and errors."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from rllib_conv import envs
from rllib_conv.envs.bandit import (
    good_arms,
    oracle_marginals,
    paper_prizes,
    user_study_prizes,
)

CONFIGS = [{"symmetric": m, "new_task": new} for m in range(5) for new in (False, True)] + [
    {"task": "user_study"},
    {"task": "user_study", "new_task": True},
    {"prizes": [[1, 0, 2], [0, 3, 3]]},
]


def reset_to_context(env, context: int) -> dict:
    """Reset with the first seed (0, 1, ...) that draws `context`; return the observations."""
    for seed in range(1000):
        obs, infos = env.reset(seed=seed)
        if infos["player_0"]["context"] == context:
            return obs
    raise AssertionError(f"no seed below 1000 draws context {context}")


def payoff(env, context: int, a0: int, a1: int) -> float:
    reset_to_context(env, context)
    _, rewards, terms, truncs, _ = env.step({"player_0": a0, "player_1": a1})
    assert terms == {"player_0": True, "player_1": True} and not any(truncs.values())
    assert rewards["player_0"] == rewards["player_1"]
    return rewards["player_0"]


@pytest.mark.parametrize("config", CONFIGS, ids=str)
def test_pettingzoo_api_and_seed(config: dict) -> None:
    parallel_api_test(envs.make("bandit", **config), num_cycles=50)
    parallel_seed_test(lambda: envs.make("bandit", **config), num_cycles=50)


def test_paper_payoffs_rule_and_symmetric_contexts() -> None:
    env = envs.make("bandit", symmetric=2)
    # Context 0 is symmetric: arms 0 and 4 both pay when both players pick the same one.
    assert payoff(env, 0, 0, 0) == 1.0
    assert payoff(env, 0, 4, 4) == 1.0
    assert payoff(env, 0, 0, 4) == 0.0  # two good arms, but no coordination
    assert payoff(env, 0, 1, 1) == 0.0  # coordinated on a bad arm
    # Context 2 is a rule context: only arm 2 pays.
    assert payoff(env, 2, 2, 2) == 1.0
    assert payoff(env, 2, 6, 6) == 0.0


def test_new_task_moves_rule_arms_and_keeps_symmetric_contexts() -> None:
    env = envs.make("bandit", symmetric=2, new_task=True)
    assert payoff(env, 2, 6, 6) == 1.0
    assert payoff(env, 2, 2, 2) == 0.0
    assert payoff(env, 3, 7, 7) == 1.0
    assert payoff(env, 0, 0, 0) == 1.0 and payoff(env, 0, 4, 4) == 1.0


def test_prize_matrices_by_hand() -> None:
    assert good_arms(paper_prizes(0)) == [(0,), (1,), (2,), (3,)]
    assert good_arms(paper_prizes(3)) == [(0, 4), (1, 5), (2, 6), (3,)]
    assert good_arms(paper_prizes(3, new_task=True)) == [(0, 4), (1, 5), (2, 6), (7,)]
    assert good_arms(paper_prizes(4, new_task=True)) == good_arms(paper_prizes(4))
    # The user-study tasks, 1-based in the paper: Train A{1} B{3,4} C{2,4}; Test A{3} B{1,2} C{2,4}.
    assert good_arms(user_study_prizes()) == [(0,), (2, 3), (1, 3)]
    assert good_arms(user_study_prizes(new_task=True)) == [(2,), (0, 1), (1, 3)]
    marg = oracle_marginals(paper_prizes(1))
    assert marg[0, 0] == marg[0, 4] == 0.5 and marg[1, 1] == 1.0 and marg.sum(axis=1).tolist() == [1.0] * 4


def test_user_study_payoffs_and_custom_prizes() -> None:
    env = envs.make("bandit", task="user_study")
    assert env.num_contexts == 3 and env.num_arms == 4
    assert payoff(env, 1, 2, 2) == 1.0 and payoff(env, 1, 3, 3) == 1.0 and payoff(env, 1, 1, 1) == 0.0
    env = envs.make("bandit", prizes=[[1, 0, 2], [0, 3, 3]])
    assert payoff(env, 0, 2, 2) == 2.0 and payoff(env, 0, 0, 0) == 1.0 and payoff(env, 1, 2, 1) == 0.0


def test_observation_is_the_one_hot_context_for_both_players() -> None:
    env = envs.make("bandit", symmetric=1)
    for c in range(4):
        obs = reset_to_context(env, c)
        for agent in env.possible_agents:
            assert obs[agent]["observation"].tolist() == np.eye(4)[c].tolist()
            assert obs[agent]["action_mask"].tolist() == [1] * 8
            assert env.observation_space(agent).contains(obs[agent])


def test_contexts_come_from_the_seeded_rng_uniformly() -> None:
    env = envs.make("bandit", symmetric=2)
    env.reset(seed=123)
    first = [env.reset()[1]["player_0"]["context"] for _ in range(4000)]
    env.reset(seed=123)
    again = [env.reset()[1]["player_0"]["context"] for _ in range(4000)]
    env.reset(seed=124)
    other = [env.reset()[1]["player_0"]["context"] for _ in range(4000)]
    assert first == again and first != other
    counts = np.bincount(first, minlength=4)
    assert (abs(counts - 1000) < 150).all(), counts  # ~5 standard deviations


def test_spaces_are_fixed() -> None:
    env = envs.make("bandit", symmetric=2)
    spaces_before = (env.observation_space("player_0"), env.action_space("player_0"))
    env.reset(seed=0)
    env.step({"player_0": 0, "player_1": 0})
    env.reset(seed=1)
    assert (env.observation_space("player_0"), env.action_space("player_0")) == spaces_before
    assert env.observation_space("player_0") is spaces_before[0]


@pytest.mark.parametrize(
    ("config", "match"),
    [
        ({"symmetric": 5}, "symmetric must be one of 0..4"),
        ({"symmetric": -1}, "symmetric"),
        ({"task": "chess"}, r"task must be one of \['paper', 'user_study'\]"),
        ({"new_task": "yes"}, "new_task must be a bool"),
        ({"prizes": [1, 2, 3]}, "prizes must be a contexts x arms matrix"),
        ({"prizes": [[1, -1]]}, "non-negative"),
        ({"render_mode": "human"}, "render_mode"),
    ],
)
def test_bad_config_names_the_argument(config: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        envs.make("bandit", **config)


@pytest.mark.parametrize("bad", [8, -1, 1.5, "2", None])
def test_actions_outside_the_space_raise(bad) -> None:
    env = envs.make("bandit", symmetric=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="player_1"):
        env.step({"player_0": 0, "player_1": bad})


def test_missing_action_and_step_after_end_raise() -> None:
    env = envs.make("bandit", symmetric=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="missing"):
        env.step({"player_0": 0})
    env.step({"player_0": 0, "player_1": 0})
    with pytest.raises(RuntimeError, match="reset"):
        env.step({"player_0": 0, "player_1": 0})


def test_render_ansi_shows_the_context() -> None:
    env = envs.make("bandit", symmetric=2, render_mode="ansi")
    reset_to_context(env, 1)
    env.step({"player_0": 5, "player_1": 5})
    text = env.render()
    assert "context 1: . # . . . # . . <- {'player_0': 5, 'player_1': 5}" in text
