"""The convention posterior (`head_init: posterior`, not in the paper): its arithmetic by hand, then through adaptation."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rllib_conv import envs
from rllib_conv.adaptation.convention_posterior import ConventionPosterior, PosteriorPlayer
from rllib_conv.common.config_files import checked
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.envs.bandit.keys import bandit_context
from rllib_conv.envs.best_response import BestResponse
from rllib_conv.envs.blocks import BLUE, HIDDEN, RED, encode_observation
from rllib_conv.envs.blocks.keys import blocks_observation
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.blocks import TEST_PERMUTATIONS, TRAIN_PERMUTATIONS, BlocksLeader, PermutationPartner, derangements
from rllib_conv.partners.episodes import episode_stream, play_batched, play_episodes
from rllib_conv.partners.hanabi import RandomLegalPartner
from rllib_conv.partners.population import from_partners
from rllib_conv.pipelines.adapt import run_adaptation
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.train import run
from rllib_conv.training import experiment

ONE_HOT = np.eye(4, dtype=np.float32)
ALL_ARMS = np.ones((4, 8), dtype=np.int8)
# Bandit, symmetric 2: contexts 0 and 1 have good arms {c, c + 4}; contexts 2 and 3 one good arm each.
LOW, HIGH = BanditConventionPartner("low", [0, 1, 2, 3]), BanditConventionPartner("high", [4, 5, 2, 3])


def moves(partner: BanditConventionPartner, contexts: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    obs, masks = ONE_HOT[contexts], ALL_ARMS[contexts]
    return obs, masks, partner.act_batch(obs, masks)


def test_one_move_by_hand() -> None:
    # The partner pulls arm 0 in context 0: "low" gives it 0.95 + 0.05/8, "high" 0.05/8, a novel convention 1/8.
    post = ConventionPosterior([LOW, HIGH], bandit_context, recombined=0.5, novel=0.1, epsilon=0.05)
    post.observe(*moves(LOW, [0]))
    low, high, novel = 0.95 + 0.05 / 8, 0.05 / 8, 1 / 8
    whole = np.array([0.25 * low, 0.25 * high, 0.5 * (0.45 * low + 0.45 * high + 0.1 * novel)])
    assert post.hypotheses() == pytest.approx(whole / whole.sum(), abs=1e-12)
    part = np.array([0.45 * low, 0.45 * high, 0.1 * novel])
    assert post.situation(0) == pytest.approx(part / part.sum(), abs=1e-12)
    assert post.situation(1) is None  # context 1 unseen
    # Without evidence: the priors.
    assert ConventionPosterior([LOW, HIGH], bandit_context).hypotheses() == pytest.approx([0.25, 0.25, 0.5])


def test_the_prediction_of_the_next_move_by_hand() -> None:
    post = ConventionPosterior([LOW, HIGH], bandit_context, recombined=0.5, novel=0.1, epsilon=0.05)
    post.observe(*moves(LOW, [0]))
    h, part = post.hypotheses(), post.situation(0)
    low, high = 0.95 * np.eye(8)[[0, 1]] + 0.05 / 8, 0.95 * np.eye(8)[[4, 5]] + 0.05 / 8  # contexts 0 and 1
    novel_seen = (np.eye(8)[0] + 0.5) / 5  # one pull of arm 0, plus a half per arm
    seen = h[0] * low[0] + h[1] * high[0] + h[2] * (part[0] * low[0] + part[1] * high[0] + part[2] * novel_seen)
    unseen = h[0] * low[1] + h[1] * high[1] + h[2] * (0.45 * low[1] + 0.45 * high[1] + 0.1 / 8)
    assert post.predictive(ONE_HOT[:2], ALL_ARMS[:2]) == pytest.approx(np.stack([seen, unseen]), abs=1e-12)
    assert post.predictive(ONE_HOT, ALL_ARMS).sum(axis=1) == pytest.approx(np.ones(4))


def blocks_posterior() -> tuple[ConventionPosterior, list[BlocksLeader], BestResponse, PermutationPartner]:
    """A posterior over blocks' training permutations (no evidence yet), their leaders as its heads, P1's planner and a
    held-out permutation partner."""
    models = [PermutationPartner(f"t{i}", list(p)) for i, p in enumerate(TRAIN_PERMUTATIONS)]
    leaders = [BlocksLeader(f"l{i}", list(p)) for i, p in enumerate(TRAIN_PERMUTATIONS)]
    planner, new = envs.best_response("blocks", {}, "player_0"), PermutationPartner("new", list(TEST_PERMUTATIONS[0]))
    return ConventionPosterior(models, blocks_observation), leaders, planner, new


def test_the_blocks_player_plans_against_the_prediction() -> None:
    # A test permutation recombines the training ones cell by cell: once the partner has answered red on
    # every cell, the ego's plan scores 20 on every goal; before any evidence, its plan is the best
    # response to the training partners' mixture, which no head is.
    post, leaders, planner, new = blocks_posterior()
    prior = PosteriorPlayer("ego", post, leaders, RandomLegalPartner(seed=0), planner=planner)
    assert prior.plan.value.min() > 12.5  # the exact 13.33 of the mixture, less the smoothing's stray moves
    empty, move1 = np.zeros(4, dtype=np.int64), []
    for cell in range(4):
        grid = empty.copy()
        grid[cell] = RED
        move1.append(encode_observation(np.full(4, HIDDEN), grid, 1, sees_goal=False))
    obs, masks = np.stack(move1), np.ones((4, 6), dtype=np.int8)
    post.observe(obs, masks, new.act_batch(obs, masks))
    assert post.hypotheses()[-1] > 0.99  # no training permutation is the new one
    player = PosteriorPlayer("ego", post, leaders, RandomLegalPartner(seed=0), planner=planner)
    seats = {"player_0": player, "player_1": new}
    assert [score for score, _ in itertools.islice(episode_stream(envs.make("blocks"), seats, seed=0), 30)] == [20.0] * 30
    # Goal red on cell 0, blue on cell 1: signal blue's cell through the new permutation, for certain.
    start = encode_observation(np.array([RED, BLUE, 0, 0]), empty, 0, sees_goal=True)[None]
    assert player.action_probs(start, masks[:1]).tolist() == [np.eye(6)[new.perm.index(1)].tolist()]


def test_a_planned_player_is_a_fixed_policy_scored_exactly_and_played_batched() -> None:
    # Its moves are the plan's, fixed before the episode: the partner's moves within one change none, so the game's
    # exact return scores it and many games play at once (the very episodes of one at a time: it is greedy).
    post, leaders, planner, new = blocks_posterior()
    player = PosteriorPlayer("ego", post, leaders, RandomLegalPartner(seed=0), planner=planner)
    assert not player.learns_in_play and player.batchable
    seats = {"player_0": player, "player_1": new}
    batched = play_batched(lambda: envs.make_scored("blocks"), seats, 240, seed=3)
    assert batched.tolist() == play_episodes(envs.make_scored("blocks"), seats, 240, seed=3).tolist()
    exact = envs.game("blocks").exact_return(seats, {})
    assert 0 < exact < 20 and exact == pytest.approx(batched.mean(), abs=4 * batched.std() / np.sqrt(240))
    unplanned = PosteriorPlayer("ego", post, leaders, RandomLegalPartner(seed=0))
    assert unplanned.learns_in_play and not unplanned.batchable
    assert envs.game("blocks").exact_return({"player_0": unplanned, "player_1": new}, {}) is None


def test_rule_moves_tell_conventions_apart_from_nothing() -> None:
    # Contexts 2 and 3: both known conventions pull the same arm, so only recombination's share can move.
    post = ConventionPosterior([LOW, HIGH], bandit_context)
    post.observe(*moves(LOW, [2, 3, 2, 3]))
    h = post.hypotheses()
    assert h[0] == pytest.approx(h[1])


def test_a_whole_known_convention_is_identified_and_a_recombined_one_is_not_taken_for_one() -> None:
    post = ConventionPosterior([LOW, HIGH], bandit_context)
    post.observe(*moves(HIGH, [0, 1, 2, 0, 1]))
    h = post.hypotheses()
    # Recombination explains it too, at a price of 0.45 per symmetric context (its chance of "high" there),
    # which repeated moves in a seen context do not raise: Occam's razor, bounded by 2 symmetric contexts.
    assert h[1] > 0.7 and h[0] < 1e-3
    assert post.situation(0).argmax() == 1 and post.situation(1).argmax() == 1
    mixed = BanditConventionPartner("mixed", [4, 1, 2, 3])  # high in context 0, low in context 1: neither whole
    post = ConventionPosterior([LOW, HIGH], bandit_context)
    post.observe(*moves(mixed, [0, 1, 0, 1]))
    h = post.hypotheses()
    assert h[2] > 0.95
    assert post.situation(0).argmax() == 1 and post.situation(1).argmax() == 0


def test_the_player_answers_by_situation_and_falls_back_where_no_convention_fits() -> None:
    # Heads: on the bandit the best answer to a convention is the convention itself.
    mixed = BanditConventionPartner("mixed", [4, 1, 2, 3])
    adapting = BanditConventionPartner("adapting", [6, 7, 2, 3])  # stands for the adapting head
    post = ConventionPosterior([LOW, HIGH], bandit_context)
    post.observe(*moves(mixed, [0, 1, 0, 1]))
    probs = PosteriorPlayer("ego", post, [LOW, HIGH], adapting).action_probs(ONE_HOT, ALL_ARMS)
    assert probs[0, 4] > 0.95 and probs[1, 1] > 0.95  # the convention each seen context follows
    assert probs[2, 2] == pytest.approx(1.0) and probs.sum(axis=1) == pytest.approx(np.ones(4))
    # A partner pulling an arm no training partner pulls in context 0: a novel convention there.
    odd = BanditConventionPartner("odd", [6, 1, 2, 3])
    post = ConventionPosterior([LOW, HIGH], bandit_context)
    post.observe(*moves(odd, [0, 0, 1]))
    assert post.situation(0)[-1] > 0.95
    probs = PosteriorPlayer("ego", post, [LOW, HIGH], adapting).action_probs(ONE_HOT, ALL_ARMS)
    assert probs[0, 6] > 0.95  # the adapting head's answer
    # Unseen contexts are the adapting head's (under recombination) or the whole conventions' (prior mixture).
    fresh = PosteriorPlayer("ego", ConventionPosterior([LOW, HIGH], bandit_context), [LOW, HIGH], adapting).action_probs(
        ONE_HOT, ALL_ARMS
    )
    assert fresh[0, [0, 4, 6]] == pytest.approx([0.25, 0.25, 0.5])


def test_sampled_play_draws_from_the_mixture() -> None:
    post = ConventionPosterior([LOW, HIGH], bandit_context)
    player = PosteriorPlayer("ego", post, [LOW, HIGH], BanditConventionPartner("adapting", [6, 7, 2, 3]), seed=3)
    arms = []
    for _ in range(4000):
        player.start_episode()
        arms.append(player.act(ONE_HOT[0], ALL_ARMS[0]))
    freq = np.bincount(arms, minlength=8) / len(arms)
    assert freq[[0, 4, 6]] == pytest.approx([0.25, 0.25, 0.5], abs=0.03)


def test_blocks_partners_are_identified_from_their_moves_within_an_episode() -> None:
    # Whole conventions only (no situation key, no planner). The ego heads are the leaders of each permutation.
    perms = [list(p) for p in derangements()[:4]]
    models = [PermutationPartner(f"p{i}", p) for i, p in enumerate(perms)]
    leaders = [BlocksLeader(f"l{i}", p) for i, p in enumerate(perms)]
    player = PosteriorPlayer("ego", ConventionPosterior(models, None), leaders, RandomLegalPartner(seed=0), seed=1)
    seats = {"player_0": player, "player_1": PermutationPartner("new", perms[2])}
    scores = [score for score, _ in itertools.islice(episode_stream(envs.make("blocks"), seats, seed=0), 40)]
    # Each episode starts from the (empty) evidence and learns within it: the partner's one telling move
    # (blue after red) comes after the ego's signal, so episodes still score less than the leader's 20.
    assert player._live.hypotheses()[2] > 0.5
    assert 0 < np.mean(scores) < 20


def test_untrainable_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="head_init 'posterior' needs the trained ego's heads"):
        AdaptConfig(runs=["r"], method="scratch", head_init="posterior")
    with pytest.raises(ValueError, match="recombined"):
        AdaptConfig(runs=["r"], head_init="posterior", posterior={"recombined": 1.5})
    with pytest.raises(ValueError, match="at least one known partner"):
        ConventionPosterior([], None)


@pytest.mark.slow
def test_adapting_to_a_training_convention_plays_its_head_after_one_update(bandit_egos, tmp_path) -> None:
    # The new partner is a training partner: its moves in one update of 16 steps identify its convention
    # (whole or context by context), and the ego plays it at once; the fresh head would still play the marginals.
    trial = Path(bandit_egos["bandit-s2-hand"].path)
    raw = {
        "name": "p",
        "runs": [str(trial)],
        "split": "train",
        "partners": ["hand-train-2"],
        "head_init": "posterior",
        "steps": 64,
    }
    curves = run_adaptation(checked(raw, AdaptConfig), out=tmp_path, storage=tmp_path / "runs")
    assert curves["steps"].tolist() == [0, 16, 32, 48, 64]
    assert abs(curves["exact_return"].iloc[0] - 0.75) < 0.05  # the prior: half the symmetric contexts right
    assert (curves["exact_return"].iloc[1:] >= 0.95).all()
    assert "picked" not in curves or curves["picked"].isna().all()  # 2 symmetric contexts never make a whole convention certain
    # With a lower bar the near-certain convention's head (and its task module) restart the adapting ego,
    # which then plays it and keeps it under PPO.
    raw = {**raw, "name": "q", "posterior": {"handover": 0.6}}
    curves = run_adaptation(checked(raw, AdaptConfig), out=tmp_path, storage=tmp_path / "runs")
    assert (curves["exact_return"].iloc[1:] >= 0.95).all()
    (trial_rows,) = [pd.read_csv(f) for f in (tmp_path / "runs" / "adapt-q").glob("*/curves.csv")]
    assert trial_rows["picked"].dropna().unique().tolist() == ["ego@hand-train-2"]


@pytest.fixture(scope="module")
def narrow_ego(ray_session, tmp_path_factory) -> tuple[str, Path]:
    """An ego trained with two partners that both pull arm 0 in context 0; its test partner pulls arm 4 there (novel)."""
    folder = tmp_path_factory.mktemp("narrow")
    pop = from_partners(
        "narrow",
        "bandit",
        {"symmetric": 2},
        train=[BanditConventionPartner("a", [0, 1, 2, 3]), BanditConventionPartner("b", [0, 5, 2, 3])],
        test=[BanditConventionPartner("novel", [4, 1, 2, 3])],
    )
    manifest = folder / "narrow.json"
    pop.save(manifest)
    config = experiment.load("tune_configs/bandit_modular.yaml", ["name=narrow", f"population={manifest}", "run.timesteps=4096"])
    results = run(config, storage=folder / "runs")
    assert not results.errors
    return str(trial_folders(results[0].path)[0]), folder


@pytest.mark.slow
def test_a_partner_following_no_known_convention_falls_back_to_fine_tuning(narrow_ego, tmp_path) -> None:
    trial, _ = narrow_ego
    common = {"runs": [trial], "split": "test", "steps": 480, "seed": 5}
    plain = run_adaptation(checked({"name": "fresh", **common}, AdaptConfig), out=tmp_path, storage=tmp_path / "runs")
    post = run_adaptation(
        checked({"name": "posterior", "head_init": "posterior", **common}, AdaptConfig), out=tmp_path, storage=tmp_path / "runs"
    )
    assert post["steps"].tolist() == plain["steps"].tolist()
    assert "picked" not in post or post["picked"].isna().all()  # no known convention is handed over
    # Context 0 is novel: the posterior leaves it to the adapting head, which PPO trains as the plain method's
    # (same seeds); context 1 follows training partner "a", whose head the posterior plays from the first update.
    assert post["exact_return"].iloc[-1] >= plain["exact_return"].iloc[-1] - 0.02
    assert plain["exact_return"].iloc[-1] > plain["exact_return"].iloc[0] + 0.1  # the plain method did learn


@pytest.mark.slow
def test_blocks_adaptation_plays_the_best_response_to_a_recombined_convention_after_one_update(blocks_ego, tmp_path) -> None:
    # A test permutation reads each cell as one of the training permutations does. In the first update's 640
    # steps the adapting ego puts red on every cell at move 1, the partner answers, and the plan against the
    # prediction scores 20 on every goal; the plain method, from the same ego, is far from it.
    common = {"runs": [blocks_ego], "split": "test", "partners": ["perm-1032"], "steps": 1280, "episodes": 40}
    # Scored as the blocks plan scores it: by the exact return alone (its plan fixes its moves before each episode).
    post = run_adaptation(
        checked({"name": "posterior", "head_init": "posterior", **common, "episodes": 0}, AdaptConfig),
        out=tmp_path,
        storage=tmp_path / "runs",
    )
    plain = run_adaptation(checked({"name": "fresh", **common}, AdaptConfig), out=tmp_path, storage=tmp_path / "runs")
    # Before, after one and two updates of exactly the protocol's 640 env steps (each replica's own moves, not
    # RLlib's per-module counts, which count the partner's final observation too: 744 per update on blocks).
    assert post["steps"].tolist() == plain["steps"].tolist() == [0, 640, 1280]
    assert (post["exact_return"].iloc[1:] == 20.0).all() and post["exact_return"].notna().all()
    assert post["mean_return"].isna().all()  # no sampled episodes
    assert plain["mean_return"].max() < 17.0
