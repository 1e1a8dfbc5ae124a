"""TrajeDi's trajectory JSD: known answers by hand (local likelihoods, values, gradients) on hand-built trajectories,
and its place in the learner (the advantages it changes, the JSD it logs)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import torch
from ray.rllib.core import ALL_MODULES
from ray.rllib.evaluation.postprocessing import Postprocessing

from rllib_conv.common import config_files
from rllib_conv.envs.replicated_game import ReplicatedGame
from rllib_conv.learners.marginal_learner import TRAJECTORY_DIVERSITY_KEY
from rllib_conv.learners.packed.fused_update import TRAIN_COLUMNS
from rllib_conv.learners.packed.rollout import Rollout, segment_lengths
from rllib_conv.learners.trajectory_diversity import local_log_likelihoods, surrogate, trajectory_diversity
from rllib_conv.pipelines.selfplay import build_joint_config
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from tests.helpers import hand_batch

# Two members, tabular policies over 2 actions whose state is the step t of a 3-step game: P[j][t] = pi_j(.|t).
P = np.array([[[0.8, 0.2], [0.6, 0.4], [0.3, 0.7]], [[0.5, 0.5], [0.1, 0.9], [0.7, 0.3]]])
# Member 0 played (0, 0, 1) and (1, 0) (a 2-step chunk); member 1 played (1, 1, 0).
EPISODES = [[(0, 0, 1), (1, 0)], [(1, 1, 0)]]
GAMMA = 0.5


def _layout(episodes: list[tuple[int, ...]]) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Steps and actions of a member's episodes end to end, and their lengths."""
    steps = np.array([t for ep in episodes for t in range(len(ep))])
    actions = np.array([a for ep in episodes for a in ep])
    return steps, actions, [len(ep) for ep in episodes]


def _member_logp(logits: torch.Tensor, episodes: list[tuple[int, ...]]) -> torch.Tensor:
    """[N, R]: log pi_j of a member's moves under every member j, from tabular `logits` [N, T, A]."""
    steps, actions, _ = _layout(episodes)
    logp = torch.log_softmax(logits, -1)
    return logp[:, torch.as_tensor(steps), torch.as_tensor(actions)]


def _by_hand(probs: np.ndarray, episodes: list[list[tuple[int, ...]]], gamma: float) -> tuple[float, list[np.ndarray]]:
    """The JSD estimate and per-move weights (less their mean), the local likelihoods as products of powers (no logs until the end)."""
    n = len(probs)
    jsd, weights = [], []
    for i, eps in enumerate(episodes):
        member_terms, w = [], []
        for ep in eps:
            T = len(ep)
            local = np.array(
                [[np.prod([probs[j, s, ep[s]] ** gamma ** abs(t - s) for s in range(T)]) for t in range(T)] for j in range(n)]
            )
            d = np.log(local[i] / local.mean(0))
            member_terms.append(d.mean())
            w += [sum(gamma ** abs(t - s) * d[s] for s in range(T)) / T for t in range(T)]
        jsd.append(np.mean(member_terms))
        weights.append((np.array(w) - np.mean(w)) / (n * len(eps)))  # minus the member's mean: the baseline
    return float(np.mean(jsd)), weights


def test_local_log_likelihoods_by_hand() -> None:
    # Segments (1, 2, 4) and (8) with gamma 0.5: 1 + 0.5*2 + 0.25*4 = 3, 0.5 + 2 + 0.5*4 = 4.5, 0.25 + 1 + 4 = 5.25, 8.
    out = local_log_likelihoods(torch.tensor([1.0, 2.0, 4.0, 8.0]), [3, 1], 0.5)
    assert out.tolist() == pytest.approx([3.0, 4.5, 5.25, 8.0])
    # gamma 0: each move alone; gamma 1: the whole segment's sum on every row.
    x = torch.tensor([[1.0, 2.0, 4.0, 8.0]])
    assert local_log_likelihoods(x, [2, 2], 0.0).tolist() == [[1.0, 2.0, 4.0, 8.0]]
    assert local_log_likelihoods(x, [2, 2], 1.0).tolist() == [[3.0, 3.0, 12.0, 12.0]]
    with pytest.raises(ValueError, match="do not cover"):
        local_log_likelihoods(x, [2, 1], 0.5)


@pytest.mark.parametrize("gamma", [0.0, GAMMA, 1.0])
def test_value_and_weights_by_hand_on_three_steps(gamma: float) -> None:
    logits = torch.log(torch.tensor(P, dtype=torch.float64))
    td = trajectory_diversity([_member_logp(logits, eps) for eps in EPISODES], [_layout(e)[2] for e in EPISODES], gamma)
    value, weights = _by_hand(P, EPISODES, gamma)
    assert td.value.item() == pytest.approx(value, abs=1e-10)
    for got, expected in zip(td.weights, weights):
        np.testing.assert_allclose(got.numpy(), expected, atol=1e-12)


def test_surrogate_gradient_by_hand() -> None:
    # d/d logits_i[t] of sum_moves w log pi_i(a|t) = sum over member i's moves at step t of w (onehot(a) - pi_i(.|t)).
    logits = torch.log(torch.tensor(P, dtype=torch.float64)).requires_grad_(True)
    logp = [_member_logp(logits, eps) for eps in EPISODES]
    td = trajectory_diversity(logp, [_layout(e)[2] for e in EPISODES], GAMMA)
    surrogate([lp[i] for i, lp in enumerate(logp)], td.weights).backward()
    _, weights = _by_hand(P, EPISODES, GAMMA)
    expected = np.zeros_like(P)
    for i, eps in enumerate(EPISODES):
        steps, actions, _ = _layout(eps)
        for w, t, a in zip(weights[i], steps, actions):
            expected[i, t] += w * (np.eye(2)[a] - P[i, t])
    np.testing.assert_allclose(logits.grad.numpy(), expected, atol=1e-12)


def _exact_jsd(logits: torch.Tensor) -> torch.Tensor:
    """H(mean_j p_j) - mean_j H(p_j) over all 2^3 trajectories of the tabular 3-step game (gamma 1)."""
    logp = torch.log_softmax(logits, -1)
    paths = torch.tensor(list(itertools.product((0, 1), repeat=3)))
    traj = torch.stack([logp[j, torch.arange(3), paths].sum(-1) for j in range(len(logits))]).exp()  # [N, 8]

    def entropy(p: torch.Tensor) -> torch.Tensor:
        return -(p * p.log()).sum(-1)

    return entropy(traj.mean(0)) - entropy(traj).mean()


def test_gamma_one_in_expectation_is_the_exact_jsd_and_its_gradient() -> None:
    """Known answer: each member's trajectories listed as often as it plays them (probabilities in 32nds), gamma 1:
    the estimate is the exact JSD of the trajectory distributions, and the surrogate's gradient is its gradient;
    the estimate's own gradient (through the log-probabilities alone) is zero."""
    probs = np.array([[[0.5, 0.5], [0.25, 0.75], [0.5, 0.5]], [[0.75, 0.25], [0.5, 0.5], [0.25, 0.75]]])
    episodes = []
    for j in range(2):
        eps = []
        for path in itertools.product((0, 1), repeat=3):
            count = 32 * np.prod([probs[j, t, a] for t, a in enumerate(path)])
            assert count == int(count)
            eps += [path] * int(count)
        episodes.append(eps)
    logits = torch.log(torch.tensor(probs, dtype=torch.float64)).requires_grad_(True)
    exact = _exact_jsd(logits)
    (exact_grad,) = torch.autograd.grad(exact, logits)
    logp = [_member_logp(logits, eps) for eps in episodes]
    td = trajectory_diversity(logp, [_layout(e)[2] for e in episodes], 1.0)
    # The estimate averages d over a trajectory's steps; at gamma 1 d is the same on every step: log(p_i / mean p).
    assert td.value.item() == pytest.approx(exact.item(), abs=1e-12)
    (pathwise,) = torch.autograd.grad(td.value, logits, retain_graph=True)
    np.testing.assert_allclose(pathwise.numpy(), 0.0, atol=1e-12)
    (estimator,) = torch.autograd.grad(surrogate([lp[i] for i, lp in enumerate(logp)], td.weights), logits)
    np.testing.assert_allclose(estimator.numpy(), exact_grad.numpy(), atol=1e-12)
    assert exact_grad.abs().max() > 1e-3  # a gradient worth checking


def test_one_step_is_the_action_jsd() -> None:
    # The bandit: one-move episodes; the local likelihood is pi_j(a|s). Members on different actions: JSD = ln 2.
    lowest = torch.finfo(torch.float64).min
    logits = torch.tensor([[0.0, lowest], [lowest, 0.0]], dtype=torch.float64)
    logp = torch.log_softmax(logits, -1)
    own = [logp[:, [0, 0, 0]], logp[:, [1, 1]]]  # member 0 played action 0 three times, member 1 action 1 twice
    td = trajectory_diversity(own, [[1, 1, 1], [1, 1]], GAMMA)
    assert td.value.item() == pytest.approx(math.log(2))
    # Members that agree: no divergence, no weight.
    same = trajectory_diversity([logp[[0, 0]][:, [0, 0]], logp[[0, 0]][:, [0]]], [[1, 1], [1]], GAMMA)
    assert same.value.item() == pytest.approx(0.0) and all(torch.all(w == 0) for w in same.weights)


def test_members_with_disjoint_trajectories_get_no_weight() -> None:
    # The JSD at its maximum (log N): d = log N on every move, so the baseline leaves nothing to push.
    lowest = torch.finfo(torch.float64).min
    logp = torch.log_softmax(torch.tensor([[0.0, lowest], [lowest, 0.0]], dtype=torch.float64), -1)
    td = trajectory_diversity([logp[:, [0, 0]], logp[:, [1]]], [[2], [1]], GAMMA)
    assert td.value.item() == pytest.approx(math.log(2))
    assert all(torch.allclose(w, torch.zeros_like(w)) for w in td.weights)


def _joint_learner(beta: float, pairs: int = 2, discount: float = GAMMA):
    """A built learner for `pairs` bandit pairs trained together with `trajectory_diversity: beta`, in this process."""
    raw = config_files.load("tune_configs/selfplay_bandit_trajedi.yaml", [], schema=SelfPlayConfig)
    raw.update({"train_pairs": pairs, "test_pairs": 0, "trajectory_diversity": beta, "trajectory_discount": discount})
    raw["model"] = {"hidden": 8}
    cfg = SelfPlayConfig.model_validate(raw).resolve()
    config = build_joint_config(cfg)
    return config.build_learner(env=ReplicatedGame(config.env_config))


def test_learner_adds_beta_times_the_weights_to_each_members_advantages() -> None:
    """By hand (numpy): each member's moves as episodes of 3, 2 and 1 moves; every member's policy on them; the local
    likelihoods, d, the weights less their mean; advantages + beta x rows x weight. The JSD is logged per seat."""
    learner = _joint_learner(0.7, pairs=3)
    seats = learner.settings.populations
    assert seats == {f"seat@player_{s}": [f"seat@player_{s}#{k}" for k in range(3)] for s in (0, 1)}
    batch = hand_batch([mid for members in seats.values() for mid in members], num_arms=8)
    data = {mid: {c: batch[mid][c] for c in TRAIN_COLUMNS} for mid in batch}
    lengths = {mid: [3, 2, 1] for mid in batch}
    columns = learner.plain_episode_columns(data, lengths)
    assert set(columns) == set(batch)
    for seat, members in seats.items():
        n, jsd = len(members), []
        for i, own in enumerate(members):
            obs = batch[own]["obs"]
            probs = [
                torch.softmax(learner.module[j].policy(obs["observations"], obs["action_mask"]).logits, -1).detach().numpy()
                for j in members
            ]
            a = batch[own]["actions"].numpy()
            logp = np.log(np.array([p[np.arange(len(a)), a] for p in probs]))  # [N, R]
            d, w, start = [], [], 0
            for T in lengths[own]:
                seg = logp[:, start : start + T]
                local = np.array([[sum(GAMMA ** abs(t - s) * seg[j, s] for s in range(T)) for t in range(T)] for j in range(n)])
                dd = local[i] - np.log(np.exp(local).mean(0))
                d.append(dd.mean())
                w += [sum(GAMMA ** abs(t - s) * dd[s] for s in range(T)) / T for t in range(T)]
                start += T
            jsd.append(np.mean(d))
            w = (np.array(w) - np.mean(w)) / (n * len(lengths[own]))
            expected = batch[own][Postprocessing.ADVANTAGES].numpy() + 0.7 * len(a) * w
            np.testing.assert_allclose(columns[own][Postprocessing.ADVANTAGES].numpy(), expected, rtol=1e-5, atol=1e-6)
        logged = learner.metrics.peek((ALL_MODULES, f"{TRAJECTORY_DIVERSITY_KEY}/{seat}"))
        assert float(logged) == pytest.approx(np.mean(jsd), abs=1e-6)  # float32: a small difference of logs
        assert np.mean(jsd) > 1e-4


def test_beta_zero_changes_nothing_and_rllib_episodes_are_refused() -> None:
    learner = _joint_learner(0.0)
    batch = hand_batch([mid for members in learner.settings.populations.values() for mid in members], num_arms=8)
    data = {mid: {c: batch[mid][c] for c in TRAIN_COLUMNS} for mid in batch}
    assert learner.plain_episode_columns(data, {mid: [1] * 6 for mid in batch}) == {}
    assert learner.plain_episode_columns(data, None) == {}  # nothing to log without episodes, nothing to add
    with pytest.raises(ValueError, match="needs the batched sampler's Rollouts"):
        _joint_learner(0.5).plain_episode_columns(data, None)


def test_segment_lengths_follow_the_rows() -> None:
    first, second = Rollout(), Rollout()
    obs = {"observations": np.zeros(2), "action_mask": np.ones(3)}
    first.rows("a").add([obs] * 4, [0, 1, 2], [0.0] * 3, [0.0] * 3, True, False)
    first.rows("a").add([obs] * 2, [0], [0.0], [0.0], False, True)
    first.rows("b").add([obs] * 3, [1, 1], [0.0] * 2, [0.0] * 2, True, False)
    second.rows("a").add([obs] * 3, [2, 2], [0.0] * 2, [0.0] * 2, True, False)
    assert segment_lengths([first, second]) == {"a": [3, 1, 2], "b": [2]}
