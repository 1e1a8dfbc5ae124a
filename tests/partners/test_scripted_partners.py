"""Scripted bandit and blocks partners score what the rules say against their own conventions."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv import envs, partners
from rllib_conv.envs.bandit import good_arms, paper_prizes
from rllib_conv.envs.blocks import PASS
from rllib_conv.partners.bandit import (
    BanditConventionPartner,
    convention_arms,
    hand_designed_codes,
    hand_designed_partners,
    random_convention_partners,
)
from rllib_conv.partners.blocks import (
    TEST_PERMUTATIONS,
    TRAIN_PERMUTATIONS,
    BlocksLeader,
    PermutationPartner,
    derangements,
)


@pytest.mark.parametrize("symmetric", range(5))
def test_hand_designed_conventions_are_balanced(symmetric: int) -> None:
    for split in ("train", "test"):
        codes = np.array(hand_designed_codes(symmetric, split)).reshape(4, symmetric)
        # Every symmetric context: two partners on the low arm, two on the high arm.
        assert (codes.sum(axis=0) == 2).all()
    train, test = set(hand_designed_codes(symmetric, "train")), set(hand_designed_codes(symmetric, "test"))
    if symmetric >= 3:
        assert not train & test  # enough distinct conventions to keep test partners new


def test_hand_designed_arms_by_hand() -> None:
    assert hand_designed_codes(2, "train") == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert convention_arms((1, 0)) == [4, 1, 2, 3]
    assert convention_arms((1, 0), new_task=True) == [4, 1, 6, 7]  # rules move, conventions stay
    assert [p.arms for p in hand_designed_partners(1, "test")] == [[4, 1, 2, 3], [4, 1, 2, 3], [0, 1, 2, 3], [0, 1, 2, 3]]


@pytest.mark.parametrize("symmetric", range(5))
@pytest.mark.parametrize("new_task", [False, True])
def test_bandit_ego_copying_the_convention_scores_one(symmetric: int, new_task: bool) -> None:
    env = envs.make("bandit", symmetric=symmetric, new_task=new_task)
    for p in hand_designed_partners(symmetric, "train", new_task) + hand_designed_partners(symmetric, "test", new_task):
        copy = BanditConventionPartner("copy", p.arms)
        scores = partners.play_episodes(env, {"player_0": copy, "player_1": p}, num_episodes=40, seed=1)
        assert scores.tolist() == [1.0] * 40


def test_bandit_mismatched_conventions_score_by_the_contexts_they_share() -> None:
    env = envs.make("bandit", symmetric=4)
    a = BanditConventionPartner("a", [0, 1, 2, 3])
    b = BanditConventionPartner("b", [4, 1, 6, 3])  # disagrees in contexts 0 and 2
    env.reset(seed=0)
    scores = partners.play_episodes(env, {"player_0": a, "player_1": b}, num_episodes=2000, seed=0)
    assert abs(scores.mean() - 0.5) < 0.05  # contexts are uniform; 2 of 4 agree


def test_random_conventions_are_seeded_good_arms() -> None:
    prizes = paper_prizes(3)
    first = [p.arms for p in random_convention_partners(prizes, 200, seed=4)]
    assert first == [p.arms for p in random_convention_partners(prizes, 200, seed=4)]
    assert first != [p.arms for p in random_convention_partners(prizes, 200, seed=5)]
    good = good_arms(prizes)
    assert all(arm in good[c] for arms in first for c, arm in enumerate(arms))
    low = np.mean([arms[0] == 0 for arms in first])
    assert 0.35 < low < 0.65  # uniform over the two good arms of context 0


def test_bandit_partner_rejects_bad_arms_and_masked_arms() -> None:
    with pytest.raises(ValueError, match="arms must be"):
        BanditConventionPartner("x", [])
    p = BanditConventionPartner("x", [0, 3, 1])
    with pytest.raises(ValueError, match="not all legal"):
        p.act(np.eye(3)[1], np.array([1, 1, 1, 0], dtype=np.int8))
    with pytest.raises(ValueError, match="knows 3 contexts"):
        p.act(np.eye(4)[3], np.ones(4, dtype=np.int8))
    obs = np.eye(3)[[2, 0, 1, 1]]
    assert p.act_batch(obs, np.ones((4, 4), dtype=np.int8)).tolist() == [1, 0, 3, 3]


def test_nine_derangements_split_three_six() -> None:
    assert len(derangements()) == 9
    assert len(TRAIN_PERMUTATIONS) == 3 and len(TEST_PERMUTATIONS) == 6
    assert set(TRAIN_PERMUTATIONS) | set(TEST_PERMUTATIONS) == set(derangements())


def _blocks_episode(leader, partner, goal, new_task=False) -> float:
    env = envs.make("blocks", new_task=new_task)
    env.reset(seed=0)
    env.goal = goal
    total = 0.0
    for agent in env.agent_iter():
        obs, reward, term, _, _ = env.last()
        if agent == "player_0":
            total += reward
        if term:
            env.step(None)
            continue
        seat = leader if agent == "player_0" else partner
        env.step(seat.act(obs["observation"], obs["action_mask"]))
    return total


@pytest.mark.parametrize("new_task", [False, True])
def test_blocks_leader_and_its_permutation_partner_score_twenty_on_every_goal(new_task: bool) -> None:
    from rllib_conv.envs.blocks import GOALS

    for perm in derangements():
        leader, partner = BlocksLeader("l", list(perm), new_task), PermutationPartner("p", list(perm))
        assert [_blocks_episode(leader, partner, g, new_task) for g in GOALS] == [20.0] * 12


def test_blocks_mismatched_permutation_scores_by_hand() -> None:
    from rllib_conv.envs.blocks import GOALS

    for perm_l in TRAIN_PERMUTATIONS:
        for perm_p in TEST_PERMUTATIONS:
            leader, partner = BlocksLeader("l", list(perm_l)), PermutationPartner("p", list(perm_p))
            for red, blue in GOALS:
                signal = perm_l.index(blue)
                # Red always reaches its goal; blue is right only if the partner reads the signal the same way.
                expected = 10.0 + 10.0 * (perm_p[signal] == blue)
                assert _blocks_episode(leader, partner, (red, blue)) == expected


def test_permutation_partner_passes_without_a_signal() -> None:
    env = envs.make("blocks")
    env.reset(seed=0)
    env.step(PASS)
    obs = env.observe("player_1")
    assert PermutationPartner("p", [1, 0, 3, 2]).act(obs["observation"], obs["action_mask"]) == PASS


def test_permutation_partner_answers_every_blue_observation_by_its_rule_in_one_batch() -> None:
    # Every grid with at most one red and one blue block, at every move, goal hidden: the rows a
    # permutation partner meets. By the rule: on move 1 with red on cell c, perm[c]; else pass.
    from rllib_conv.envs.blocks import BLUE, EMPTY, HIDDEN, NUM_MOVES, RED, encode_observation

    perm = (2, 3, 1, 0)
    rows, expected = [], []
    for red in [None, 0, 1, 2, 3]:
        for blue in [None, 0, 1, 2, 3]:
            if red is not None and red == blue:
                continue
            grid = np.full(4, EMPTY)
            if red is not None:
                grid[red] = RED
            if blue is not None:
                grid[blue] = BLUE
            for move in range(NUM_MOVES):
                rows.append(encode_observation(np.full(4, HIDDEN), grid, move, sees_goal=False))
                expected.append(perm[red] if move == 1 and red is not None else PASS)
    partner = PermutationPartner("p", list(perm))
    masks = np.ones((len(rows), 6), dtype=np.int8)
    assert partner.act_batch(np.stack(rows), masks).tolist() == expected
    assert [partner.act(o, m) for o, m in zip(rows, masks)] == expected
    assert partner.act_batch(np.zeros((0, len(rows[0])), dtype=np.float32), masks[:0]).tolist() == []
