"""The convention posterior's information-parity controls: known answers for the lookup and the two planners."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv import envs
from rllib_conv.adaptation.context_lookup import ContextLookup
from rllib_conv.adaptation.counts_planner import CountsPlanner
from rllib_conv.adaptation.prior_planner import PriorPlanner
from rllib_conv.common.config_files import checked
from rllib_conv.envs.bandit.keys import bandit_context
from rllib_conv.envs.best_response import best_response_return
from rllib_conv.envs.blocks.best_response import BlocksBestResponse
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.base import Partner, SampledPartner
from rllib_conv.partners.blocks import TEST_PERMUTATIONS, TRAIN_PERMUTATIONS, PermutationPartner
from rllib_conv.pipelines.adapt import run_adaptation
from rllib_conv.pipelines.adapt_config import AdaptConfig

ARMS = 8


class FixedMarginal(SampledPartner):
    """A stand-in for the task module: fixed probabilities per observation (uneven, so its rows are recognisable)."""

    kind = "test_marginal"

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        masks = np.asarray(action_masks, dtype=np.float64)
        rows = np.arange(1, masks.shape[1] + 1, dtype=np.float64) * masks
        rows[np.arange(len(rows)), np.asarray(observations).argmax(axis=1) % masks.shape[1]] += 5.0
        return rows * masks / (rows * masks).sum(axis=1, keepdims=True)

    def params(self) -> dict:
        return {}


def test_the_lookup_plays_the_partners_seen_arm_and_the_marginal_elsewhere() -> None:
    contexts, masks = np.eye(4, dtype=np.float32), np.ones((4, ARMS), dtype=np.int8)
    partner, marginal = BanditConventionPartner("p", [4, 5, 2, 3]), FixedMarginal("task")
    lookup = ContextLookup(bandit_context)
    player = lookup.player("ego", marginal)
    assert np.allclose(player.action_probs(contexts, masks), marginal.action_probs(contexts, masks))  # nothing seen yet
    seen = contexts[[0, 2, 0]]  # the partner moves in contexts 0 and 2 only
    lookup.observe(seen, np.full(3, -1), partner.act_batch(seen, masks[:3]))
    probs = player.action_probs(contexts, masks)
    assert np.array_equal(probs[[0, 2]], np.eye(ARMS)[[4, 2]])
    assert np.allclose(probs[[1, 3]], marginal.action_probs(contexts[[1, 3]], masks[[1, 3]]))
    assert [player.act(c, m) for c, m in zip(contexts[[0, 2]], masks[[0, 2]])] == [4, 2]
    # Its exact return against the partner: 1 in the seen contexts, the marginal's share of the partner's arm elsewhere.
    prizes = envs.make("bandit").prizes
    expected = np.mean([prizes[c, partner.arms[c]] * probs[c, partner.arms[c]] for c in range(4)])
    assert envs.game("bandit").exact_return({"player_0": player, "player_1": partner}, {}) == pytest.approx(expected)


def test_a_control_plays_batched_where_its_fallback_can_and_chooses_as_it_does_one_at_a_time() -> None:
    contexts, masks = np.eye(4, dtype=np.float32), np.ones((4, ARMS), dtype=np.int8)
    lookup = ContextLookup(bandit_context)
    lookup.observe(contexts[[0, 2]], np.full(2, -1), np.array([4, 2]))
    player = lookup.player("ego", BanditConventionPartner("fallback", [7, 6, 5, 1]))  # greedy: a function of the context
    assert player.batchable
    assert player.act_batch(contexts, masks).tolist() == [player.act(c, m) for c, m in zip(contexts, masks)] == [4, 6, 2, 1]
    assert not lookup.player("ego", OneAtATime("fallback")).batchable


class OneAtATime(Partner):
    """A partner that does not declare `batchable` (as a user's own may not)."""

    kind = "test_one_at_a_time"

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return 0

    def params(self) -> dict:
        return {}


def test_the_lookup_answers_a_mixed_partner_with_its_most_played_arm_lowest_on_ties() -> None:
    lookup, context = ContextLookup(bandit_context), np.eye(4, dtype=np.float32)[1]
    lookup.observe(np.stack([context] * 3), np.zeros(3, dtype=np.int64), np.array([6, 1, 6]))
    assert lookup.seen(context) == 6
    lookup.observe(context[None], np.zeros(1, dtype=np.int64), np.array([1]))
    assert lookup.seen(context) == 1  # 2 against 2: the lower arm


def blocks_evidence(partner: PermutationPartner, episodes: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What the ego's seat records of `partner` while P1 plays uniformly at random (`envs.seen_moves`)."""
    env, rng = PettingZooMultiAgentEnv(envs.make("blocks")), np.random.default_rng(seed)
    env.record_seen_moves("player_0")
    for episode in range(episodes):
        env.reset(seed=seed * 10_000 + episode)
        while env.env.agents:
            agent = env.env.agent_selection
            observation = env.env.observe(agent)
            action = (
                int(rng.integers(6))
                if agent == "player_0"
                else partner.act(observation["observation"], observation["action_mask"])
            )
            env.step({agent: action})
    return env.take_seen_moves()


def exact(player, partner) -> float:
    return envs.game("blocks").exact_return({"player_0": player, "player_1": partner}, {})


@pytest.mark.parametrize("perm", [TRAIN_PERMUTATIONS[0], TEST_PERMUTATIONS[2]])
def test_the_counts_planner_reaches_the_best_response_to_a_fixed_partner_once_it_has_seen_its_moves(perm) -> None:
    partner, fallback = PermutationPartner("p", list(perm)), FixedMarginal("task")
    best = best_response_return("blocks", {}, "player_0", partner)
    assert best == pytest.approx(20.0)
    counts = CountsPlanner(BlocksBestResponse())
    assert exact(counts.player("ego", fallback), partner) < best - 5  # knowing nothing, it cannot guess the convention
    counts.observe(*blocks_evidence(partner, episodes=300, seed=0))
    assert counts.counts.sum() == 300 * 3
    assert exact(counts.player("ego", fallback), partner) == pytest.approx(best)
    # Its model of a seen situation is the partner's move, with Laplace's one imagined move of each kind.
    situations, masks = counts.planner.situations()
    seen = counts.counts.sum(axis=1) > 0
    moves = partner.act_batch(situations[seen], masks[seen])
    n = counts.counts[seen].sum(axis=1)
    assert np.allclose(counts.predictive()[seen][np.arange(len(moves)), moves], (n + 1) / (n + 6))


def test_the_frozen_prior_planner_never_changes_its_play() -> None:
    partner = PermutationPartner("p", list(TEST_PERMUTATIONS[0]))
    models = [PermutationPartner(f"t{k}", list(p)) for k, p in enumerate(TRAIN_PERMUTATIONS)]
    control, fallback = PriorPlanner(BlocksBestResponse(), models), FixedMarginal("task")
    before = control.player("ego", fallback)
    states, masks = blocks_states()
    first = before.action_probs(states, masks)
    control.observe(*blocks_evidence(partner, episodes=50, seed=1))
    assert np.array_equal(control.player("ego", fallback).action_probs(states, masks), first)
    assert exact(control.player("ego", fallback), partner) == exact(before, partner)


def blocks_states() -> tuple[np.ndarray, np.ndarray]:
    """P1's observations along random games (every goal, several grids), with their masks."""
    env, rng, rows = envs.make("blocks"), np.random.default_rng(2), []
    for episode in range(60):
        env.reset(seed=episode)
        for agent in env.agent_iter():
            observation, _, done, truncated, _ = env.last()
            if done or truncated:
                env.step(None)
                continue
            if agent == "player_0":
                rows.append((observation["observation"], observation["action_mask"]))
            env.step(int(rng.integers(6)))
    return np.stack([o for o, _ in rows]), np.stack([m for _, m in rows])


@pytest.mark.slow
def test_the_bandit_lookup_adapts_through_the_pipeline_to_the_partners_arm(bandit_egos, tmp_path) -> None:
    # At step 0 it has seen nothing: the trained task module alone (the marginal: 3/4 on Arms 2). After one update of
    # 16 pulls every context has been seen (with near certainty) and it plays the partner's arm in each: 1.
    trial = bandit_egos["bandit-s2-hand"].path
    raw = {"name": "l", "runs": [trial], "partners": ["hand-test-1"], "head_init": "lookup", "steps": 48, "episodes": 0}
    curves = run_adaptation(checked(raw, AdaptConfig), out=tmp_path, storage=tmp_path / "runs")
    assert curves["steps"].tolist() == [0, 16, 32, 48]
    assert abs(curves["exact_return"].iloc[0] - 0.75) < 0.05
    assert (curves["exact_return"].iloc[1:] == 1.0).all()


@pytest.mark.slow
def test_the_blocks_planner_controls_through_the_pipeline(blocks_ego, tmp_path) -> None:
    # The counts planner learns the test permutation from its moves in the first update and then plays its best
    # response (20); the frozen prior's plan never changes, so neither does its score.
    common = {"runs": [blocks_ego], "split": "test", "partners": ["perm-1032"], "steps": 1280, "episodes": 40}
    counts = run_adaptation(
        checked({"name": "counts", "head_init": "counts-planner", **common}, AdaptConfig), out=tmp_path, storage=tmp_path / "runs"
    )
    prior = run_adaptation(
        checked({"name": "prior", "head_init": "prior-planner", **common}, AdaptConfig), out=tmp_path, storage=tmp_path / "runs"
    )
    assert counts["steps"].tolist() == prior["steps"].tolist() == [0, 640, 1280]
    assert counts["mean_return"].iloc[0] < 20.0 and (counts["mean_return"].iloc[1:] == 20.0).all()
    assert prior["exact_return"].nunique() == 1
