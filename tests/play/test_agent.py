"""The adapting agent: known answers of the partner-module update, speed of coordination, carry-over."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rllib_conv.common.user_study_table import USER_STUDY_GOOD_ARMS
from rllib_conv.envs.bandit import user_study_prizes
from rllib_conv.envs.bandit.keys import bandit_context
from rllib_conv.envs.blocks import GOALS, PASS, RED, encode_observation
from rllib_conv.play.agent import (
    AdaptiveAgent,
    PartnerTable,
    bandit_observation,
    bandit_oracle_prior,
    bandit_targets,
    blocks_p1_targets,
    blocks_p2_targets,
    responder_prior,
    uniform_prior,
)

ETA = 3.0
ARMS = 4
CONTEXTS = 3
ALL = np.ones(ARMS, dtype=np.int8)
TRAIN = bandit_oracle_prior(user_study_prizes(new_task=False))
TEST = bandit_oracle_prior(user_study_prizes(new_task=True))
A_CONTEXT, B, C = 0, 1, 2  # A has one good arm; symmetric contexts of the Train task: good arms (2, 3) and (1, 3)


def sigmoid(x: float) -> float:
    return 1.0 / (1.0 + math.exp(-x))


def observe(agent: AdaptiveAgent, context: int, arm: int) -> None:
    # As the bandit room does after a try: the person's pick is both the hindsight target and their move.
    picked = bandit_targets(context, CONTEXTS, ARMS, arm)
    agent.learn(picked)
    agent.watch(picked)


def policy(agent: AdaptiveAgent, context: int) -> np.ndarray:
    return agent.policy(bandit_observation(context, CONTEXTS), ALL)


def test_before_any_try_the_agent_plays_the_task_module_marginals() -> None:
    agent = AdaptiveAgent(TRAIN, ETA, seed=0)
    for context, good in enumerate(USER_STUDY_GOOD_ARMS["train"]):
        expected = np.zeros(ARMS)
        expected[list(good)] = 1 / len(good)
        np.testing.assert_allclose(policy(agent, context), expected, atol=1e-5)


def test_one_observed_pick_on_a_symmetric_context_gives_sigmoid_eta() -> None:
    # Prior 1/2, 1/2 on the good arms: h moves by +eta/2 and -eta/2, so the log-odds become eta.
    agent = AdaptiveAgent(TRAIN, ETA, seed=0)
    observe(agent, B, 3)
    p = policy(agent, B)
    assert p[3] == pytest.approx(sigmoid(ETA), abs=1e-5)  # 0.9526
    assert p[2] == pytest.approx(1 - sigmoid(ETA), abs=1e-5)
    np.testing.assert_allclose(policy(agent, C), [0, 0.5, 0, 0.5], atol=1e-5)  # other contexts untouched


def test_uniform_prior_known_answer() -> None:
    agent = AdaptiveAgent(uniform_prior, ETA, seed=0)
    observe(agent, 0, 1)
    p = policy(agent, 0)
    assert p[1] == pytest.approx(math.exp(ETA) / (math.exp(ETA) + 3), abs=1e-9)  # 0.870
    np.testing.assert_allclose(p[[0, 2, 3]], (1 - p[1]) / 3, atol=1e-12)


def test_update_is_one_cross_entropy_gradient_step_on_the_partner_logits() -> None:
    prior = np.array([0.1, 0.2, 0.3, 0.4])
    agent = AdaptiveAgent(lambda obs, mask: np.broadcast_to(prior, mask.shape), step_size=0.7, seed=0)
    obs = bandit_observation(0, CONTEXTS)

    def loss(h: np.ndarray, target: int) -> float:
        logits = np.log(prior) + h
        return -(logits[target] - np.log(np.exp(logits).sum()))

    h = np.zeros(ARMS)
    for target in (2, 0, 2):
        numeric = np.array([(loss(h + d, target) - loss(h - d, target)) / 2e-6 for d in np.eye(ARMS) * 1e-6])
        h = h - 0.7 * numeric
        agent.learn([(obs, ALL, target)])
        np.testing.assert_allclose(agent.partner.logits(obs, ARMS), h, atol=1e-6)


def test_one_odd_pick_does_not_override_a_rule() -> None:
    # Context A has one good arm; a person's slip on arm 3 must not make the agent follow.
    agent = AdaptiveAgent(TRAIN, ETA, seed=0)
    observe(agent, 0, 2)
    assert policy(agent, 0)[0] > 0.999


def play_consistent(agent: AdaptiveAgent, context: int, person_arm: int, tries: int = 5) -> list[bool]:
    """Whether the agent matched a person who pulls `person_arm` on every try."""
    obs = bandit_observation(context, CONTEXTS)
    matched = []
    for _ in range(tries):
        matched.append(agent.act(obs, ALL) == person_arm)
        observe(agent, context, person_arm)
    return matched


def test_consistent_person_is_matched_on_a_symmetric_context_in_about_two_tries() -> None:
    runs = np.array([play_consistent(AdaptiveAgent(TRAIN, ETA, seed=s), B, 2) for s in range(400)])
    first = np.where(runs.any(axis=1), runs.argmax(axis=1) + 1, 99)
    # Try 1 is a coin flip between the two good arms; from try 2 P(match) >= sigmoid(3) = 0.95:
    # E[first coordination] = 1/2 * 1 + 1/2 * (0.953 * 2 + ...) = 1.52.
    assert 0.4 < runs[:, 0].mean() < 0.6
    assert 1.4 < first.mean() < 1.7
    assert (first <= 2).mean() > 0.93 and (first <= 3).mean() > 0.99
    assert runs[:, 1:].mean() > 0.94  # tries 2-5: a stochastic policy still slips a few percent


def test_greedy_agent_matches_from_the_second_try_on() -> None:
    for seed in range(50):
        assert all(play_consistent(AdaptiveAgent(TRAIN, ETA, greedy=True, seed=seed), C, 3)[1:])


def test_conventions_carry_over_to_the_same_symmetry_on_the_test_task_and_rules_win_elsewhere() -> None:
    agent = AdaptiveAgent(TRAIN, ETA, seed=0)
    for _ in range(5):
        observe(agent, B, 3)  # Train-B good (2, 3)
        observe(agent, C, 1)  # Train-C good (1, 3)
    agent.prior = TEST  # Test-B good (0, 1); Test-C good (1, 3), the same as Train-C
    assert policy(agent, C)[1] > 0.95  # the person's Train-C convention, on the first Test-C try
    p = policy(agent, B)
    assert p[3] < 0.01  # the stale Train-B convention is not a good arm any more
    assert p[0] == pytest.approx(0.5, abs=0.01) and p[1] == pytest.approx(0.5, abs=0.01)


def test_bad_settings_and_targets_are_refused() -> None:
    with pytest.raises(ValueError, match="step_size must be a positive number"):
        PartnerTable(0.0)
    with pytest.raises(ValueError, match="step_size"):
        AdaptiveAgent(TRAIN, float("nan"))
    agent = AdaptiveAgent(TRAIN, ETA, seed=0)
    with pytest.raises(ValueError, match="hindsight target 7 is not a legal action"):
        agent.learn([(bandit_observation(0, CONTEXTS), ALL, 7)])
    with pytest.raises(ValueError, match="allows no action"):
        agent.policy(bandit_observation(0, CONTEXTS), np.zeros(ARMS, dtype=np.int8))


# --- blocks ----------------------------------------------------------------------------


def move0_obs(red: int, blue: int) -> np.ndarray:
    goal = np.zeros(4, dtype=np.int64)
    goal[red], goal[blue] = 1, 2
    return encode_observation(goal, np.zeros(4, dtype=np.int64), 0, sees_goal=True)


def test_p1_learns_which_signal_makes_the_person_place_blue() -> None:
    # The agent (P1) put red on cell 0; the person (P2) answered with blue on cell 3.
    history = [(1, 0), (2, 3), (1, 2), (2, PASS), (1, PASS), (2, PASS)]
    targets = blocks_p1_targets(history)
    assert sorted(int(o[:16].reshape(4, 4).argmax(1).tolist().index(1)) for o, _, _ in targets) == [0, 1, 2]  # red goals
    assert {t for _, _, t in targets} == {0}
    agent = AdaptiveAgent(uniform_prior, ETA, seed=0)
    agent.learn(targets)
    mask = np.ones(6, dtype=np.int8)
    # Uniform over 6 moves, one step: e^eta / (e^eta + 5) on "red on cell 0" for every goal with blue on 3.
    for red, blue in GOALS:
        p = agent.policy(move0_obs(red, blue), mask)
        if blue == 3:
            assert p[0] == pytest.approx(math.exp(ETA) / (math.exp(ETA) + 5), abs=1e-9)
        else:
            np.testing.assert_allclose(p, 1 / 6)


def test_p1_learns_nothing_when_the_person_never_answers_a_red_block() -> None:
    assert blocks_p1_targets([(1, PASS), (2, 3), (1, PASS), (2, PASS), (1, PASS), (2, PASS)]) == []


def test_p2_responder_prior_and_its_update_from_the_revealed_goal() -> None:
    grid = np.array([0, RED, 0, 0])
    obs = encode_observation(np.zeros(4, dtype=np.int64), grid, 1, sees_goal=False)
    mask = np.ones(6, dtype=np.int8)
    np.testing.assert_allclose(responder_prior(obs[None], mask[None])[0], [1 / 3, 0, 1 / 3, 1 / 3, 0, 0])
    later = encode_observation(np.zeros(4, dtype=np.int64), grid, 3, sees_goal=False)
    np.testing.assert_allclose(responder_prior(later[None], mask[None])[0], [0, 0, 0, 0, 0, 1])

    history = [(1, 1), (2, 0), (1, PASS), (2, PASS), (1, PASS), (2, PASS)]
    targets = blocks_p2_targets(history, goal=(1, 2))
    assert len(targets) == 1 and targets[0][2] == 2
    np.testing.assert_array_equal(targets[0][0], obs)  # keyed by what P2 saw at move 1
    agent = AdaptiveAgent(responder_prior, ETA, seed=0)
    agent.learn(targets)
    assert agent.policy(obs, mask)[2] == pytest.approx(math.exp(ETA) / (math.exp(ETA) + 2), abs=1e-5)  # 0.909


# --- the convention posterior around the agent (`--adapter posterior`, not in the paper) ---------


def convention_agent(seed: int = 0):
    from rllib_conv.partners.bandit import BanditConventionPartner
    from rllib_conv.play.convention_agent import ConventionSource

    # Two training partners of the Train task, each the other's opposite in contexts B and C; on the
    # bandit a partner's best response is its own convention, so they stand in for the ego's heads too.
    low, high = BanditConventionPartner("low", [0, 2, 1]), BanditConventionPartner("high", [0, 3, 3])
    return ConventionSource(models=[low, high], known=[low, high], key=bandit_context).agent(
        AdaptiveAgent(TRAIN, ETA, seed=seed), TRAIN, seed=seed
    )


def test_the_convention_agent_plays_a_recognised_convention_at_once_and_the_table_elsewhere() -> None:
    agent = convention_agent()
    np.testing.assert_allclose(policy(agent, B), [0, 0, 0.5, 0.5], atol=1e-5)  # no evidence: the marginals
    observe(agent, B, 3)  # "high" in B
    # By hand (4 arms, epsilon 0.05): the pick's likelihood is 0.0125 under "low", 0.9625 under "high", 1/4 novel.
    low, high, novel = 0.0125, 0.9625, 0.25
    whole = np.array([0.25 * low, 0.25 * high, 0.5 * (0.45 * low + 0.45 * high + 0.1 * novel)])
    whole /= whole.sum()
    part = np.array([0.45 * low, 0.45 * high, 0.1 * novel]) / (0.45 * low + 0.45 * high + 0.1 * novel)
    table = agent.table.policy(bandit_observation(B, CONTEXTS), ALL)[3]
    assert table == pytest.approx(sigmoid(ETA), abs=1e-5)  # the table alone: 0.953
    expected = whole[1] + whole[2] * (part[1] + part[2] * table)
    assert policy(agent, B)[3] == pytest.approx(expected, abs=1e-9)
    assert expected > 0.98
    # C unseen: whole "high" answers 3; recombination leaves C to the table (the marginals, 1/2 on arm 3).
    p = policy(agent, C)
    post = agent.posterior.hypotheses()
    assert p[3] == pytest.approx(post[1] + post[2] * 0.5 + post[0] * 0.0, abs=1e-5) and p[3] > 0.6
    # A pick no training partner makes in B (arm 1: legal, not good): a novel convention there, left to the table.
    odd = convention_agent()
    for _ in range(3):
        observe(odd, B, 1)
    assert odd.posterior.situation(B)[-1] > 0.95
    np.testing.assert_allclose(policy(odd, B), odd.table.policy(bandit_observation(B, CONTEXTS), ALL), atol=1e-3)


def test_on_another_task_the_convention_agent_is_the_paper_agent_with_its_table() -> None:
    agent = convention_agent()
    observe(agent, C, 1)
    agent.prior = TEST
    reference = AdaptiveAgent(TRAIN, ETA, seed=0)
    observe(reference, C, 1)
    reference.prior = TEST
    for context in range(CONTEXTS):
        np.testing.assert_allclose(policy(agent, context), policy(reference, context), atol=1e-12)
    evidence = agent.posterior.hypotheses().copy()
    observe(agent, B, 2)  # a Test-task pick: into the table only
    np.testing.assert_allclose(agent.posterior.hypotheses(), evidence)
    assert agent.act(bandit_observation(A_CONTEXT, CONTEXTS), ALL) == 2  # Test A's one good arm
