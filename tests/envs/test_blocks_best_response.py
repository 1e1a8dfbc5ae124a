"""Blocks best response: P1's exact plan against a P2 given by its move probabilities per observation."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from rllib_conv import envs
from rllib_conv.envs.blocks import GOALS, NUM_ACTIONS, PASS
from rllib_conv.envs.blocks.best_response import BlocksBestResponse, all_grids
from rllib_conv.envs.blocks.keys import blocks_observation
from rllib_conv.partners.base import Partner
from rllib_conv.partners.blocks import TEST_PERMUTATIONS, TRAIN_PERMUTATIONS, PermutationPartner
from rllib_conv.partners.episodes import episode_stream

PLANNER = BlocksBestResponse()


def table(partner: PermutationPartner, planner: BlocksBestResponse = PLANNER) -> np.ndarray:
    """A deterministic partner's moves as one-hot probabilities per situation."""
    obs, masks = planner.situations()
    return np.eye(NUM_ACTIONS)[[partner.act(o, m) for o, m in zip(obs, masks)]]


def test_the_situations_are_every_p2_observation_once() -> None:
    obs, masks = PLANNER.situations()
    assert len(all_grids()) == 21 and obs.shape == (3 * 21, 35) and masks.all()
    assert len({blocks_observation(o) for o in obs}) == len(obs)


@pytest.mark.parametrize("perm", [TRAIN_PERMUTATIONS[0], TEST_PERMUTATIONS[3]])
def test_the_plan_against_a_known_permutation_scores_20_on_every_goal(perm) -> None:
    partner = PermutationPartner("p", list(perm))
    plan = PLANNER.plan(table(partner))
    assert plan.value == pytest.approx([20.0] * len(GOALS))
    scores = [
        s
        for s, _ in itertools.islice(
            episode_stream(envs.make("blocks"), {"player_0": _Planned(plan), "player_1": partner}, seed=0), 60
        )
    ]
    assert scores == [20.0] * 60


def test_the_plan_against_a_mixture_of_permutations_by_hand() -> None:
    # The 3 training permutations read each cell as 3 different blue cells: whatever P1 signals, blue lands
    # right with chance 1/3, and P1 can still put red on its goal: 10 + 10/3.
    mixture = np.mean([table(PermutationPartner("p", list(p))) for p in TRAIN_PERMUTATIONS], axis=0)
    assert PLANNER.plan(mixture).value == pytest.approx([10 + 10 / 3] * len(GOALS))


def test_the_new_task_plan_keeps_red_off_both_goal_cells() -> None:
    planner = BlocksBestResponse(new_task=True)
    partner = PermutationPartner("p", list(TRAIN_PERMUTATIONS[1]))
    plan = planner.plan(table(partner, planner))
    assert plan.value == pytest.approx([20.0] * len(GOALS))
    scores = [
        s
        for s, _ in itertools.islice(
            episode_stream(envs.make("blocks", new_task=True), {"player_0": _Planned(plan), "player_1": partner}, seed=1), 30
        )
    ]
    assert scores == [20.0] * 30


def test_a_partner_that_moves_blue_late_is_planned_for() -> None:
    # P2 passes until its last move, then puts blue on red's cell + 1 (mod 4). P1's last move (4) can put red
    # on its goal or on the cell before blue's, not both, unless they are the same cell: 20 on those goals,
    # 10 on the others.
    obs, masks = PLANNER.situations()
    late = np.zeros((len(obs), NUM_ACTIONS))
    for s, o in enumerate(obs):
        seen = envs.blocks.decode_observation(o)
        red = envs.blocks.block_cell(seen["grid"], envs.blocks.RED)
        late[s, (red + 1) % 4 if seen["move"] == 5 and red is not None else PASS] = 1.0
    assert PLANNER.plan(late).value == pytest.approx([20.0 if (blue - red) % 4 == 1 else 10.0 for red, blue in GOALS])


def test_only_p1_is_planned_for() -> None:
    assert envs.best_response("blocks", {}, "player_1") is None
    assert isinstance(envs.best_response("blocks", {"new_task": True}, "player_0"), BlocksBestResponse)
    assert envs.best_response("bandit", {}, "player_0") is None
    obs, _ = PLANNER.situations()
    assert PLANNER.plan(np.full((len(obs), NUM_ACTIONS), 1 / NUM_ACTIONS)).act(obs[0]) is None  # P2's observation


class _Planned(Partner):
    """P1 playing a plan, as a seat for `episode_stream`."""

    kind = "planned"
    deterministic = True

    def __init__(self, plan) -> None:
        super().__init__("planned")
        self.plan = plan

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return self.plan.act(observation)

    def params(self) -> dict:
        return {}
