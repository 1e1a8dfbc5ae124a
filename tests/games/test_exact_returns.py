"""The games' exact expected returns (`GameRecord.exact_return`) against sampled play and against known answers."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv import envs
from rllib_conv.envs.blocks.env import NUM_ACTIONS, PASS
from rllib_conv.partners import get
from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import play_episodes


class Uniform(Partner):
    """Every legal move alike: what a fresh network plays, with known probabilities."""

    kind = "test_uniform"

    def __init__(self, name: str = "uniform", seed: int = 0) -> None:
        super().__init__(name)
        self.rng = np.random.default_rng(seed)

    def act(self, observation, action_mask) -> int:
        return int(self.rng.choice(np.flatnonzero(action_mask)))

    def action_probs(self, observations, action_masks) -> np.ndarray:
        masks = np.asarray(action_masks, dtype=np.float64)
        return masks / masks.sum(axis=1, keepdims=True)

    def params(self) -> dict:
        return {}


class Passer(Partner):
    kind = "test_passer"
    deterministic = True

    def act(self, observation, action_mask) -> int:
        return PASS

    def params(self) -> dict:
        return {}


class Learner(Uniform):
    kind = "test_learner"
    learns_in_play = True


def test_blocks_exact_return_known_answers() -> None:
    exact = envs.game("blocks").exact_return
    # Nobody places a block: 0. P1 uniform with a passing P2: red ends on its goal cell when P1's last placing
    # move there is not undone; by symmetry over cells, P(red on a given cell) = P(last non-pass move is "place c").
    assert exact({"player_0": Passer("a"), "player_1": Passer("b")}, {}) == 0.0
    # P1's three uniform moves over 6 actions: the red block ends on cell c iff the last move that is not a pass places
    # it on c: sum over k = 0..2 trailing passes of (1/6)^k * (1/6) = (1 + 1/6 + 1/36) / 6.
    p_red_home = (1 + 1 / 6 + 1 / 36) / 6
    assert exact({"player_0": Uniform(), "player_1": Passer("b")}, {}) == pytest.approx(10 * p_red_home)
    assert NUM_ACTIONS == 6


@pytest.mark.parametrize("partner", ["blocks-perm", "uniform"])
def test_blocks_exact_return_matches_sampled_play(partner: str) -> None:
    other = get("blocks-perm").partners[0].build() if partner == "blocks-perm" else Uniform("p2", seed=3)
    players = {"player_0": Uniform(seed=1), "player_1": other}
    exact = envs.game("blocks").exact_return(players, {})
    scores = play_episodes(envs.make("blocks"), players, 20_000, seed=0)
    assert abs(scores.mean() - exact) < 4 * scores.std() / np.sqrt(len(scores))


def test_no_exact_return_for_players_that_learn_within_an_episode_or_hide_their_probabilities() -> None:
    blocks, bandit = envs.game("blocks").exact_return, envs.game("bandit").exact_return
    assert blocks({"player_0": Learner(), "player_1": Passer("b")}, {}) is None
    # On the bandit an episode is one move: a learner is scored as it stands.
    assert bandit({"player_0": Learner(), "player_1": Uniform()}, {"symmetric": 2}) == pytest.approx(
        np.mean(envs.make("bandit", symmetric=2).prizes.sum(axis=1)) / 8**2
    )

    class Opaque(Uniform):
        kind = "test_opaque"
        action_probs = Partner.action_probs  # stochastic and silent: the base refuses

    assert blocks({"player_0": Opaque(), "player_1": Passer("b")}, {}) is None
    assert bandit({"player_0": Opaque(), "player_1": Uniform()}, {}) is None
    assert envs.game("hanabi").exact_return is None and envs.game("overcooked").exact_return is None
