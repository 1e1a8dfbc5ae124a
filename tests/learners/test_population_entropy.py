"""MEP's population entropy: known answers by hand (values and gradient), and its place in the learner's loss."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from rllib_conv.common import config_files
from rllib_conv.envs.replicated_game import ReplicatedGame
from rllib_conv.learners.marginal_learner import POPULATION_ENTROPY_KEY
from rllib_conv.learners.population_entropy import population_entropy
from rllib_conv.pipelines.selfplay import build_joint_config
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from tests.helpers import hand_batch


def test_entropy_of_the_mean_policy_by_hand() -> None:
    # State 1: (0.5, 0.5) and (0.8, 0.2) -> mean (0.65, 0.35): H = -(0.65 ln 0.65 + 0.35 ln 0.35) = 0.64744
    # State 2: (0.9, 0.1) and (0.1, 0.9) -> mean (0.5, 0.5): H = ln 2 = 0.69315 (each member alone: 0.32508)
    p1 = torch.tensor([[0.5, 0.5], [0.9, 0.1]])
    p2 = torch.tensor([[0.8, 0.2], [0.1, 0.9]])
    logits = torch.log(torch.stack([p1, p2]))
    by_hand = (-(0.65 * math.log(0.65) + 0.35 * math.log(0.35)) + math.log(2)) / 2
    assert population_entropy(logits).item() == pytest.approx(by_hand, abs=1e-6)
    assert by_hand == pytest.approx((0.64744 + 0.69315) / 2, abs=1e-5)


def test_gradient_by_hand() -> None:
    # d H(mean) / d logits_i[b] = (1/N) p_i[b] (g[b] - sum_a p_i[a] g[a]), g[a] = -(ln mean[a] + 1), per state, / B states.
    # One state, member 1 (0.5, 0.5), member 2 (0.8, 0.2): mean (0.65, 0.35), g = (-0.56922, 0.04982),
    # sum_a p_1[a] g[a] = -0.25970, so member 1's gradient is 0.5 * 0.5 * (-0.30952, 0.30952) = (-0.07738, 0.07738).
    logits = torch.log(torch.tensor([[[0.5, 0.5]], [[0.8, 0.2]]])).requires_grad_(True)
    population_entropy(logits).backward()
    assert logits.grad[0, 0].tolist() == pytest.approx([-0.07738, 0.07738], abs=1e-5)
    # The same rule for every member and state, in numpy, on random logits with a masked action.
    rng = np.random.default_rng(0)
    raw = rng.normal(size=(3, 4, 5)).astype(np.float32)
    raw[:, :, 4] = torch.finfo(torch.float32).min  # an illegal action: probability 0 for everyone
    x = torch.tensor(raw, requires_grad=True)
    population_entropy(x).backward()
    p = np.exp(raw - raw.max(-1, keepdims=True))
    p /= p.sum(-1, keepdims=True)
    mean = p.mean(0)
    g = np.where(mean > 0, -(np.log(np.maximum(mean, 1e-30)) + 1), 0.0)
    expected = p * (g - (p * g).sum(-1, keepdims=True)) / (3 * 4)
    np.testing.assert_allclose(x.grad.numpy(), expected, atol=1e-6)
    assert np.isfinite(x.grad.numpy()).all()


def test_obvious_answers() -> None:
    # Members that agree: PE is their own entropy. Members on different arms: ln N. One member: its entropy.
    lowest = torch.finfo(torch.float32).min
    same = torch.tensor([[[0.0, 1.0, 2.0]]]).expand(4, 1, 3)
    own = torch.distributions.Categorical(logits=same[0]).entropy().item()
    assert population_entropy(same).item() == pytest.approx(own, abs=1e-6)
    apart = torch.full((3, 1, 3), lowest)
    for i in range(3):
        apart[i, 0, i] = 0.0
    assert population_entropy(apart).item() == pytest.approx(math.log(3), abs=1e-6)
    assert population_entropy(same[:1]).item() == pytest.approx(own, abs=1e-6)


def _joint_learner(alpha: float, pairs: int = 2):
    """A built learner for `pairs` bandit pairs trained together (`population_entropy: alpha`), in this process."""
    raw = config_files.load("tune_configs/selfplay_bandit_mep.yaml", [], schema=SelfPlayConfig)
    raw.update({"train_pairs": pairs, "test_pairs": 0, "population_entropy": alpha, "model": {"hidden": 8}})
    cfg = SelfPlayConfig.model_validate(raw).resolve()
    config = build_joint_config(cfg)
    return config.build_learner(env=ReplicatedGame(config.env_config))


def test_learner_loss_adds_minus_alpha_times_each_seats_pe() -> None:
    learner = _joint_learner(0.7, pairs=3)
    seats = learner.settings.populations
    assert seats == {f"seat@player_{s}": [f"seat@player_{s}#{k}" for k in range(3)] for s in (0, 1)}
    batch = hand_batch([mid for members in seats.values() for mid in members], num_arms=8)
    losses = learner.compute_losses(fwd_out=learner.module.forward_train(batch), batch=batch)
    # By hand: every member of a seat on every member's rows of that seat, the mean of their softmaxes, its entropy.
    expected = 0.0
    for members in seats.values():
        obs = {key: torch.cat([batch[mid]["obs"][key] for mid in members]) for key in ("observations", "action_mask")}
        probs = np.mean(
            [
                torch.softmax(learner.module[mid].policy(obs["observations"], obs["action_mask"]).logits, -1).detach().numpy()
                for mid in members
            ],
            axis=0,
        )
        expected += float(np.mean(-(probs * np.log(probs)).sum(-1)))
    assert losses[POPULATION_ENTROPY_KEY].item() == pytest.approx(-0.7 * expected, rel=1e-5)


def test_alpha_zero_adds_no_term() -> None:
    learner = _joint_learner(0.0)
    batch = hand_batch([mid for members in learner.settings.populations.values() for mid in members], num_arms=8)
    losses = learner.compute_losses(fwd_out=learner.module.forward_train(batch), batch=batch)
    assert POPULATION_ENTROPY_KEY not in losses and not learner.loss_reads_plain_terms
