"""Best-response bounds (`envs.best_response_return`): the best ego's expected score against a known partner, exact.

Known answers in closed form: on the bandit the best response pulls, per context, the arm the
partner's pulls pay most on, so a 70/30 split between the good arms of both symmetric
contexts bounds the score at (0.7 + 0.7 + 1 + 1) / 4 = 0.85; on blocks a P2 that follows its
permutation but slips with probability `noise` to a uniform cell lands blue right with
probability 1 - noise + noise / 4, and P1 always places red: 10 + 10 (1 - 3 noise / 4).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from rllib_conv import envs
from rllib_conv.envs.blocks import BLUE, GOALS, NUM_ACTIONS, NUM_MOVES, RED, encode_observation
from rllib_conv.envs.blocks.best_response import all_grids
from rllib_conv.partners.bandit import BanditConventionPartner, BanditMixedPartner
from rllib_conv.partners.base import Partner
from rllib_conv.partners.blocks import BlocksLeader, NoisyPermutationPartner, PermutationPartner
from rllib_conv.partners.episodes import play_episodes

S2 = {"symmetric": 2}


def split_partner(p: float) -> BanditMixedPartner:
    """Symmetric contexts 0 and 1: the low arm with probability p, the high arm otherwise; rule contexts: their arm."""
    probs = np.zeros((4, 8))
    probs[0, [0, 4]] = probs[1, [1, 5]] = [p, 1 - p]
    probs[2, 2] = probs[3, 3] = 1.0
    return BanditMixedPartner("split", probs.tolist())


class Unsaid(Partner):
    """A stochastic partner that does not say what it draws from."""

    kind = "test_unsaid"

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return 0

    def params(self) -> dict:
        return {}


@pytest.mark.parametrize(("p", "bound"), [(1.0, 1.0), (0.7, 0.85), (0.5, 0.75), (0.2, 0.9)])
def test_the_bandit_bound_of_a_split_partner_is_its_larger_share_in_the_symmetric_contexts(p, bound) -> None:
    for seat in ("player_0", "player_1"):  # the bandit is symmetric
        assert envs.best_response_return("bandit", S2, seat, split_partner(p)) == pytest.approx(bound)


def test_the_bandit_bound_counts_only_prizes_and_is_zero_for_a_partner_who_never_pulls_one() -> None:
    assert envs.best_response_return("bandit", S2, "player_0", BanditConventionPartner("c", [4, 1, 2, 3])) == 1.0
    assert envs.best_response_return("bandit", S2, "player_0", BanditConventionPartner("c", [0, 1, 6, 3])) == 0.75
    assert envs.best_response_return("bandit", S2, "player_0", BanditConventionPartner("none", [1, 0, 0, 0])) == 0.0
    assert envs.best_response_return("bandit", S2, "player_0", Unsaid("u")) is None


def test_no_bandit_convention_beats_the_bound_and_the_best_one_reaches_it() -> None:
    partner = split_partner(0.7)
    exact = envs.game("bandit").exact_return
    returns = [
        exact({"player_0": BanditConventionPartner("ego", list(arms)), "player_1": partner}, S2)
        for arms in itertools.product(range(8), repeat=2)  # every choice in the symmetric contexts
        for arms in [(*arms, 2, 3)]
    ]
    assert max(returns) == pytest.approx(envs.best_response_return("bandit", S2, "player_0", partner))


@pytest.mark.parametrize("noise", [0.0, 0.2, 0.5, 1.0])
def test_the_blocks_bound_of_a_slipping_permutation_partner_is_known_and_its_leader_reaches_it(noise) -> None:
    partner = NoisyPermutationPartner("slips", [1, 0, 3, 2], noise)
    bound = envs.best_response_return("blocks", {}, "player_0", partner)
    assert bound == pytest.approx(10 + 10 * (1 - 0.75 * noise))
    leader = BlocksLeader("leader", [1, 0, 3, 2])
    assert envs.game("blocks").exact_return({"player_0": leader, "player_1": partner}, {}) == pytest.approx(bound)
    if 0 < noise < 1:  # sampled play agrees with the exact value
        scores = play_episodes(envs.make_scored("blocks"), {"player_0": leader, "player_1": partner}, 400, seed=1)
        assert abs(scores.mean() - bound) <= 4 * scores.std(ddof=1) / np.sqrt(len(scores))


def test_every_permutation_partner_is_bounded_by_20_and_unknowns_are_none() -> None:
    for perm in itertools.permutations(range(4)):
        assert envs.best_response_return("blocks", {}, "player_0", PermutationPartner("p", list(perm))) == 20.0
    partner = PermutationPartner("p", [1, 0, 3, 2])
    assert envs.best_response_return("blocks", {}, "player_1", partner) is None  # P2 would need to infer the goal
    assert envs.best_response_return("blocks", {}, "player_0", Unsaid("u")) is None
    assert envs.best_response_return("hanabi", {}, "player_0", partner) is None  # no exact bound declared


@pytest.mark.parametrize("new_task", [False, True])
def test_a_blocks_plan_has_a_legal_move_at_every_move_of_p1_and_none_elsewhere(new_task: bool) -> None:
    # The `Plan` contract players rely on to be fixed policies within an episode (the planned convention posterior).
    planner = envs.best_response("blocks", {"new_task": new_task}, "player_0")
    situations, masks = planner.situations()
    plan = planner.plan(np.full(masks.shape, 1.0 / masks.shape[1]))  # against a uniformly random P2
    goals = []
    for red, blue in GOALS:
        goal = np.zeros(4, dtype=np.int64)
        goal[red], goal[blue] = RED, BLUE
        goals.append(goal)
    p1 = [
        encode_observation(goal, grid, move, sees_goal=True)
        for goal in goals
        for grid in all_grids()
        for move in range(0, NUM_MOVES, 2)
    ]
    assert len(p1) == 12 * 21 * 3 and all(plan.act(obs) in range(NUM_ACTIONS) for obs in p1)
    assert all(plan.act(obs) is None for obs in situations)  # P2's observations: not the planning seat's move
