"""Method variants by config (agg, no_task_logits, low-dim z, oracle), action masking, oracles."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rllib_conv.envs.bandit.oracle import bandit_states
from rllib_conv.envs.blocks import BLUE, PASS, RED, encode_observation
from rllib_conv.envs.oracles import oracle_for
from rllib_conv.modules import AGG_HEAD_ID, TASK_ID
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.evaluate import head_probs, task_probs
from tests.helpers import bandit_setup, build_learner, plain_ego


def test_agg_is_one_network_for_all_partners() -> None:
    setup = bandit_setup(method="agg")
    assert setup.head_ids == [AGG_HEAD_ID]
    learner = build_learner(setup)
    assert learner.module.head_ids() == [f"{AGG_HEAD_ID}#0"] and learner.module[STACK_ID].heads == 1
    assert plain_ego(setup).head_ids() == [AGG_HEAD_ID]


def test_no_task_logits_ignores_the_task_logits() -> None:
    module = plain_ego(bandit_setup(method="no_task_logits"))
    obs, mask = bandit_states({"symmetric": 2})
    head = module.head_ids()[0]
    before = head_probs(module, head, obs, mask)
    with torch.no_grad():
        module[TASK_ID].pi_out[0].bias.add_(5.0 * torch.arange(8.0))  # task logits change, z does not
    np.testing.assert_allclose(head_probs(module, head, obs, mask), before, atol=1e-6)
    assert not np.allclose(task_probs(module, obs, mask), 1 / 8)


def test_modular_policy_adds_task_and_head_logits() -> None:
    module = plain_ego(bandit_setup(lam=0.5))
    obs, mask = bandit_states({"symmetric": 2})
    head = module.head_ids()[0]
    with torch.no_grad():
        module[TASK_ID].pi_out[0].bias.copy_(torch.tensor([3.0, 0, 0, 0, 0, 0, 0, 0]))
    o = torch.as_tensor(obs)
    z, task_logits = module[TASK_ID].policy(o, None)
    expected = torch.softmax(task_logits + module[head].pi(z), dim=-1).detach().numpy()
    np.testing.assert_allclose(head_probs(module, head, obs, mask), expected, atol=1e-6)
    assert head_probs(module, head, obs, mask)[:, 0].min() > 0.5  # the task's preference shows


def test_low_dimensional_z() -> None:
    module = plain_ego(bandit_setup(model={"hidden": 30, "z_dim": 5}))
    assert module[TASK_ID].pi_tower[-2].out_features == 5
    assert module[module.head_ids()[0]].pi[0].in_features == 5


def test_oracle_puts_the_policy_on_optimal_actions_only() -> None:
    module = plain_ego(bandit_setup(method="oracle"))
    obs, mask = bandit_states({"symmetric": 2})
    optimal = oracle_for("bandit", {"symmetric": 2})(obs)
    np.testing.assert_allclose(task_probs(module, obs, mask), optimal / optimal.sum(axis=1, keepdims=True), atol=1e-6)
    for head in module.head_ids():
        assert (head_probs(module, head, obs, mask)[optimal == 0] < 1e-6).all()


def test_masked_actions_get_zero_probability_and_finite_gradients() -> None:
    module = plain_ego(bandit_setup(lam=0.5))
    obs, _ = bandit_states({"symmetric": 2})
    mask = np.ones((4, 8), dtype=np.int8)
    mask[:, [1, 2, 7]] = 0
    head = module.head_ids()[0]
    assert (head_probs(module, head, obs, mask)[:, [1, 2, 7]] == 0).all()
    assert (task_probs(module, obs, mask)[:, [1, 2, 7]] == 0).all()
    o, m = torch.as_tensor(obs), torch.as_tensor(mask, dtype=torch.float32)
    z, tl = module[TASK_ID].policy(o, m)
    logp = torch.log_softmax(module[head].logits(z, tl, m), dim=-1)[:, 0].sum()
    logp.backward()
    assert all(torch.isfinite(p.grad).all() for p in module[TASK_ID].parameters() if p.grad is not None)


def _p1_obs(goal_red: int, goal_blue: int, red: int | None, move: int) -> np.ndarray:
    goal = np.zeros(4)
    goal[goal_red], goal[goal_blue] = RED, BLUE
    grid = np.zeros(4)
    if red is not None:
        grid[red] = RED
    return encode_observation(goal, grid, move, sees_goal=True)


@pytest.mark.parametrize(
    ("new_task", "state", "optimal"),
    [
        (False, (0, 3, None, 0), [0, 1, 2]),  # signal: any cell but the blue goal
        (False, (0, 3, 2, 2), [0]),  # then red to its goal
        (False, (0, 3, 0, 2), [0, PASS]),  # already there: pass or re-place
        (False, (1, 2, 3, 4), [1]),
        (True, (0, 3, 2, 2), [2, PASS]),  # new task: red already on a goal-empty cell stays
        (True, (0, 3, 0, 4), [1, 2]),
    ],
)
def test_blocks_oracle_hand_rule(new_task: bool, state: tuple, optimal: list[int]) -> None:
    out = oracle_for("blocks", {"new_task": new_task})(_p1_obs(*state)[None])[0]
    assert np.flatnonzero(out).tolist() == sorted(optimal)


@pytest.mark.parametrize("method", ["agg", "no_task_logits", "oracle"])
@pytest.mark.slow
def test_every_method_trains_an_iteration(ray_session, method: str) -> None:
    from rllib_conv.training.experiment import ExperimentConfig

    exp = ExperimentConfig(
        population="bandit-s2-hand", method=method, model={"hidden": 8}, ppo={"rollout_per_partner": 16, "num_epochs": 1}
    )
    algo = build_ppo_config(resolve(exp)).build_algo()
    try:
        result = algo.train()
    finally:
        algo.stop()
    assert result["env_runners"]["num_env_steps_sampled_lifetime"] >= 64


@pytest.mark.slow
def test_hanabi_ego_only_ever_plays_legal_moves(ray_session) -> None:
    from rllib_conv.training.experiment import ExperimentConfig

    # HanabiEnv raises on any illegal move, so a clean iteration proves sampling is masked.
    exp = ExperimentConfig(
        population="hanabi-scripted",
        lam=0.5,
        model={"hidden": 16},
        ppo={"rollout_per_partner": 200, "minibatch_size": 50, "num_epochs": 1},
    )
    algo = build_ppo_config(resolve(exp)).build_algo()
    try:
        result = algo.train()
    finally:
        algo.stop()
    assert result["env_runners"]["num_env_steps_sampled_lifetime"] >= 200


def test_identical_moves_are_merged_before_comparing_marginals() -> None:
    from rllib_conv.envs.oracles import canonical_actions
    from rllib_conv.training.marginal_distance import merge_actions

    # Red already on its goal (cell 0): placing it on 0 again is the same move as passing.
    obs = _p1_obs(0, 3, 0, 2)[None]
    canon = canonical_actions("blocks", obs, 6)
    assert canon[0].tolist() == [PASS, 1, 2, 3, 4, PASS]
    merged = merge_actions(np.array([[0.3, 0.1, 0.0, 0.0, 0.0, 0.6]]), canon)
    assert merged[0].tolist() == pytest.approx([0.0, 0.1, 0.0, 0.0, 0.0, 0.9])
    # Red off the grid: removing it is a pass too.
    assert canonical_actions("blocks", _p1_obs(0, 3, None, 2)[None], 6)[0].tolist() == [0, 1, 2, 3, PASS, PASS]
    assert canonical_actions("bandit", np.eye(4)[:1], 8)[0].tolist() == list(range(8))
