"""Tests for the pyhanabi-backed small-Hanabi AEC env, checked against HLE itself."""

from __future__ import annotations

import json
import re
import warnings
from collections import Counter
from typing import Callable

import numpy as np
import pytest
from hanabi_learning_environment import pyhanabi
from pettingzoo.test import api_test, seed_test

from rllib_conv.envs.hanabi import (
    HanabiEnv,
    HanabiMoveIds,
    card_knowledge_layout,
    decode_card_knowledge,
)

PAPER = {}  # the env's defaults are the paper's config
TWO_COLOURS = {"colors": 2}
BIGGER = {"colors": 3, "ranks": 4, "players": 3, "hand_size": 3, "max_information_tokens": 5, "max_life_tokens": 2}
FULL = {"colors": 5, "ranks": 5, "players": 2, "hand_size": 5, "max_information_tokens": 8, "max_life_tokens": 3}

PLAY0, PLAY1, DISCARD0 = 2, 3, 0  # move ids in the paper's config (hand size 2)


def seat(agent: str) -> int:
    return int(agent.rsplit("_", 1)[1])


def hle_legal_ids(env: HanabiEnv) -> set[int]:
    """The move ids HLE itself says are legal for the acting player."""
    return {env._game.get_move_uid(m) for m in env.state.legal_moves()}


def play_episode(env: HanabiEnv, choose: Callable[[HanabiEnv, np.ndarray], int], seed: int | None) -> dict:
    """Play one game with `choose(env, mask) -> move id`; return its trajectory and reward sums."""
    env.reset(seed=seed)
    trajectory, reward_sums, steps, step_rewards = [], Counter(), 0, []
    for agent in env.agent_iter():
        obs, _, term, trunc, _ = env.last()
        if term or trunc:
            env.step(None)
            continue
        action = choose(env, obs["action_mask"])
        trajectory.append((agent, action, obs["observation"].tobytes()))
        env.step(action)
        steps += 1
        step_rewards.append(env.rewards[agent])
        for a, r in env.rewards.items():
            reward_sums[a] += r
    return {
        "trajectory": trajectory,
        "rewards": reward_sums,
        "step_rewards": step_rewards,
        "steps": steps,
        "score": env.state.score(),
    }


def random_choice(rng: np.random.Generator) -> Callable[[HanabiEnv, np.ndarray], int]:
    def choose(env: HanabiEnv, mask: np.ndarray) -> int:
        legal = np.flatnonzero(mask)
        return int(legal[rng.integers(len(legal))])

    return choose


def first_seed(cond: Callable[[HanabiEnv], bool], **config) -> HanabiEnv:
    """Return an env reset with the smallest seed whose start state satisfies `cond`."""
    env = HanabiEnv(**config)
    for s in range(200):
        env.reset(seed=s)
        if cond(env):
            return env
    raise AssertionError("no seed in 0..199 gives the wanted start state")


def acting_hand(env: HanabiEnv) -> list:
    return env.state.player_hands()[env.state.cur_player()]


# --------------------------------------------------------------------------- API
@pytest.mark.parametrize("config", [PAPER, TWO_COLOURS], ids=["paper", "two_colours"])
def test_pettingzoo_api_and_seed_tests(config):
    with warnings.catch_warnings():
        # The API test warns about Dict observations, which are this project's convention.
        warnings.simplefilter("ignore")
        api_test(HanabiEnv(**config), num_cycles=100)
        seed_test(lambda: HanabiEnv(**config), num_cycles=100)


def test_paper_config_spaces_and_metadata():
    env = HanabiEnv()
    assert env.possible_agents == ["player_0", "player_1"]
    space = env.observation_space("player_0")
    assert space["observation"].shape == (108,) and space["observation"].dtype == np.float32
    assert space["action_mask"].shape == (10,) and space["action_mask"].dtype == np.int8
    assert env.action_space("player_1").n == 10
    assert env.metadata == {"name": "hanabi_v0", "render_modes": ["ansi"], "is_parallelizable": False}
    env.reset(seed=0)
    assert env.observation_space("player_0") is space  # spaces never change


@pytest.mark.parametrize("config", [PAPER, TWO_COLOURS, BIGGER, FULL])
def test_move_id_layout_matches_hle(config):
    env = HanabiEnv(**config)
    env.reset(seed=0)
    ids = env.move_ids
    game = env._game
    assert ids.num_moves == game.max_moves() == env.num_moves
    h, p = env.config["hand_size"], env.config["players"]
    for i in range(h):
        assert game.get_move_uid(pyhanabi.HanabiMove.get_discard_move(i)) == ids.discard(i)
        assert game.get_move_uid(pyhanabi.HanabiMove.get_play_move(i)) == ids.play(i)
    for off in range(1, p):
        for c in range(env.config["colors"]):
            assert game.get_move_uid(pyhanabi.HanabiMove.get_reveal_color_move(off, c)) == ids.reveal_color(off, c)
        for r in range(env.config["ranks"]):
            assert game.get_move_uid(pyhanabi.HanabiMove.get_reveal_rank_move(off, r)) == ids.reveal_rank(off, r)


# ------------------------------------------------------------------ rule cases
def test_start_mask_equals_hle_legal_moves():
    env = HanabiEnv()
    for s in range(20):
        env.reset(seed=s)
        agent = env.agent_selection
        assert seat(agent) == env.state.cur_player()
        mask = env.observe(agent)["action_mask"]
        assert set(np.flatnonzero(mask).tolist()) == hle_legal_ids(env)
        # Information tokens start full, so discarding is illegal and nothing else is yet.
        assert not mask[:2].any() and mask[PLAY0] and mask[PLAY1]
        other = env.possible_agents[1 - seat(agent)]
        assert not env.observe(other)["action_mask"].any()


def test_hint_spends_an_information_token():
    env = HanabiEnv()
    env.reset(seed=0)
    agent = env.agent_selection
    hint = int(np.flatnonzero(env.observe(agent)["action_mask"][4:])[0]) + 4
    env.step(hint)
    assert env.state.information_tokens() == 2
    assert all(info["information_tokens"] == 2 for info in env.infos.values())
    assert all(r == 0.0 for r in env.rewards.values())


def test_discard_regains_a_token_and_is_illegal_at_the_cap():
    env = HanabiEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="legal actions"):
        env.step(DISCARD0)  # tokens are at the maximum of 3
    hint = int(np.flatnonzero(env.observe(env.agent_selection)["action_mask"][4:])[0]) + 4
    env.step(hint)
    assert env.state.information_tokens() == 2
    env.step(DISCARD0)
    assert env.state.information_tokens() == 3
    assert env.infos[env.agent_selection]["information_tokens"] == 3
    assert not env.observe(env.agent_selection)["action_mask"][:2].any()


def test_tokens_never_exceed_their_maxima_in_random_play():
    env = HanabiEnv(**TWO_COLOURS)
    rng = np.random.default_rng(0)
    for s in range(30):
        env.reset(seed=s)
        while not env.state.is_terminal():
            assert 0 <= env.state.information_tokens() <= 3 and 0 <= env.state.life_tokens() <= 3
            env.step(random_choice(rng)(env, env.legal_action_mask(env.state.cur_player())))


def test_misplay_costs_a_life_token():
    env = first_seed(lambda e: acting_hand(e)[0].rank() > 0)  # nothing but a 1 is playable at the start
    env.step(PLAY0)
    assert env.state.life_tokens() == 2
    assert env.state.fireworks() == [0]
    assert len(env.state.discard_pile()) == 1  # a misplayed card goes to the discards
    assert all(r == 0.0 for r in env.rewards.values())
    assert all(info["life_tokens"] == 2 and info["score"] == 0 for info in env.infos.values())


def test_successful_play_scores_one_for_everybody():
    env = first_seed(lambda e: acting_hand(e)[0].rank() == 0)
    env.step(PLAY0)
    assert env.state.fireworks() == [1]
    assert env.state.life_tokens() == 3
    assert env.rewards == {"player_0": 1.0, "player_1": 1.0}
    assert env.state.score() == 1 and all(info["score"] == 1 for info in env.infos.values())
    assert env.last()[1] == 1.0  # the next actor is told about the shared reward too


def test_losing_all_lives_ends_the_game_and_rewards_sum_to_zero():
    """Play one card, then misplay until no lives are left: the last move takes the point back."""

    def oracle(env: HanabiEnv, mask: np.ndarray) -> int:
        hand = acting_hand(env)
        fireworks = env.state.fireworks()[0]
        for i, card in enumerate(hand):
            if (card.rank() == fireworks) == (env.state.score() == 0):
                return env.move_ids.play(i)
        return int(np.flatnonzero(mask)[-1])

    env = HanabiEnv()
    for s in range(200):
        result = play_episode(env, oracle, seed=s)
        fireworks = sum(env.state.fireworks())
        if env.state.life_tokens() == 0 and fireworks > 0:
            break
    else:
        raise AssertionError("no seed loses all lives after scoring")
    assert env.state.end_of_game_status() == pyhanabi.HanabiEndOfGameType.OUT_OF_LIFE_TOKENS
    assert env.state.score() == 0
    assert result["rewards"] == {"player_0": 0.0, "player_1": 0.0}
    # The move that lost the last life took back every point built so far.
    assert result["step_rewards"][-1] == -fireworks
    assert sum(r for r in result["step_rewards"] if r > 0) == fireworks
    assert not env.agents  # every agent was stepped out after termination


def test_long_random_episode_score_equals_summed_rewards():
    """Full-size Hanabi, mostly hints and discards, so the deck runs out."""
    rng = np.random.default_rng(1)

    def mostly_safe(env: HanabiEnv, mask: np.ndarray) -> int:
        legal = np.flatnonzero(mask)
        plays = (legal >= env.move_ids.play(0)) & (legal < env.move_ids.play(env.config["hand_size"]))
        safe = legal[~plays]
        pool = legal if not len(safe) or rng.random() < 0.03 else safe
        return int(pool[rng.integers(len(pool))])

    env = HanabiEnv(**FULL)
    for s in range(3):
        result = play_episode(env, mostly_safe, seed=s)
        assert result["steps"] > 40
        assert env.state.is_terminal()
        assert set(result["rewards"].values()) == {float(env.state.score())}
    for s in range(20):  # plain random play, including games lost on life tokens
        result = play_episode(HanabiEnv(**TWO_COLOURS), random_choice(rng), seed=s)
        assert set(result["rewards"].values()) == {float(result["score"])}


def test_rewards_and_infos_are_shared_plain_values():
    env = HanabiEnv()
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    while env.agents and not env.terminations[env.agent_selection]:
        env.step(random_choice(rng)(env, env.observe(env.agent_selection)["action_mask"]))
        assert len(set(env.rewards.values())) == 1
        json.dumps(env.infos)
        assert {"score", "life_tokens", "information_tokens"} <= set(env.infos["player_0"])


# ---------------------------------------------------------------- bad inputs
@pytest.mark.parametrize("action", [-1, 10, 100, 1.5, "2", None, np.float32(2.5)])
def test_malformed_actions_raise_and_name_the_legal_ones(action):
    env = HanabiEnv()
    env.reset(seed=0)
    before = str(env.state)
    legal = np.flatnonzero(env.observe(env.agent_selection)["action_mask"]).tolist()
    with pytest.raises(ValueError, match=r"legal actions: " + re.escape(str(legal))):
        env.step(action)
    assert str(env.state) == before  # nothing happened


def test_currently_illegal_move_raises_and_is_not_substituted():
    env = first_seed(lambda e: not e.legal_action_mask(e.state.cur_player())[4:].all())
    mask = env.legal_action_mask(env.state.cur_player())
    illegal = int(np.flatnonzero(mask == 0)[-1])
    before = str(env.state)
    with pytest.raises(ValueError, match=rf"action {illegal} is not legal.*legal actions: \["):
        env.step(illegal)
    assert str(env.state) == before


def test_numpy_integer_actions_are_accepted():
    env = HanabiEnv()
    env.reset(seed=0)
    env.step(np.int64(PLAY0))
    assert len(env.state.move_history()) > 4


def test_stepping_a_finished_game_needs_none():
    env = HanabiEnv()
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    while not env.terminations[env.agent_selection]:
        env.step(random_choice(rng)(env, env.observe(env.agent_selection)["action_mask"]))
    with pytest.raises(ValueError):
        env.step(PLAY0)
    env.step(None)
    env.step(None)
    assert env.agents == []


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"colors": 0}, "colors"),
        ({"colors": 6}, "colors"),
        ({"ranks": 0}, "ranks"),
        ({"players": 7}, "players"),
        ({"players": 1}, "players"),
        ({"hand_size": 0}, "hand_size"),
        ({"hand_size": 3, "ranks": 1}, "hand_size"),  # 3 cards cannot fill two hands of 3
        ({"max_life_tokens": -1}, "max_life_tokens"),
        ({"max_life_tokens": 0}, "max_life_tokens"),
        ({"max_information_tokens": -3}, "max_information_tokens"),
        ({"max_information_tokens": 10**12}, "max_information_tokens"),
        ({"observation_type": 3}, "observation_type"),
        ({"colors": 1.5}, "colors"),
        ({"players": True}, "players"),
        ({"random_start_player": "yes"}, "random_start_player"),
        ({"render_mode": "human"}, "render_mode"),
    ],
)
def test_bad_configs_raise_naming_the_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        HanabiEnv(**kwargs)


def test_unknown_keyword_raises_type_error_naming_it():
    with pytest.raises(TypeError, match="num_colours"):
        HanabiEnv(num_colours=2)


# --------------------------------------------------------------- observations
def check_decoded_against_hle(env: HanabiEnv, player: int) -> None:
    cfg = env.config
    vec = env.observe(f"player_{player}")["observation"]
    hle_obs = env.state.observation(player)
    # The env's fast string decoding must equal pyhanabi's own encoder.
    assert vec.tolist() == env._encoder.encode(hle_obs)
    keys = ("colors", "ranks", "players", "hand_size", "max_information_tokens", "max_life_tokens")
    decoded = decode_card_knowledge(vec, **{k: cfg[k] for k in keys})
    hands = hle_obs.observed_hands()
    assert decoded["hands"][0] == []
    assert decoded["hands"][1:] == [[(c.color(), c.rank()) for c in hand] for hand in hands[1:]]
    assert decoded["missing_card"] == [len(hand) < cfg["hand_size"] for hand in hands]
    assert decoded["fireworks"] == hle_obs.fireworks()
    assert decoded["information_tokens"] == hle_obs.information_tokens()
    assert decoded["life_tokens"] == hle_obs.life_tokens()
    assert decoded["deck_size"] == hle_obs.deck_size()
    discards = Counter((c.color(), c.rank()) for c in hle_obs.discard_pile())
    assert decoded["discard_counts"] == [[discards[(c, r)] for r in range(cfg["ranks"])] for c in range(cfg["colors"])]
    for p, cards in enumerate(hle_obs.card_knowledge()):
        expected = [
            {
                "possible": {
                    (c, r)
                    for c in range(cfg["colors"])
                    if k.color_plausible(c)
                    for r in range(cfg["ranks"])
                    if k.rank_plausible(r)
                },
                "color": k.color(),
                "rank": k.rank(),
            }
            for k in cards
        ]
        assert decoded["knowledge"][p] == expected
    assert decoded["own_possible"] == [k["possible"] for k in decoded["knowledge"][0]]
    # The true identity of each own card is always among its possibilities.
    own = env.state.player_hands()[player]
    assert all((c.color(), c.rank()) in poss for c, poss in zip(own, decoded["own_possible"]))


@pytest.mark.parametrize("config", [PAPER, TWO_COLOURS, BIGGER], ids=["paper", "two_colours", "bigger"])
def test_decode_card_knowledge_matches_hle_observations(config):
    env = HanabiEnv(**config)
    rng = np.random.default_rng(0)
    checked = 0
    for s in range(25):
        env.reset(seed=s)
        while True:
            for p in range(env.config["players"]):
                check_decoded_against_hle(env, p)
                checked += 1
            if env.state.is_terminal():
                break
            env.step(random_choice(rng)(env, env.legal_action_mask(env.state.cur_player())))
    assert checked > 300


def test_decode_handles_minimal_observations_and_rejects_wrong_lengths():
    env = HanabiEnv(observation_type=0)
    env.reset(seed=0)
    vec = env.observe(env.agent_selection)["observation"]
    assert len(vec) == card_knowledge_layout(1, 5, 2, 2, 3, 3)["card_knowledge"][0]
    decoded = decode_card_knowledge(vec)
    assert decoded["knowledge"] is None and decoded["own_possible"] is None
    assert decoded["information_tokens"] == 3
    with pytest.raises(ValueError, match="length 107"):
        decode_card_knowledge(np.zeros(107))


def test_observations_are_copies_not_the_cache():
    env = HanabiEnv()
    env.reset(seed=0)
    obs = env.observe(env.agent_selection)
    obs["observation"][:] = 7
    obs["action_mask"][:] = 0
    again = env.observe(env.agent_selection)
    assert again["observation"].max() == 1 and again["action_mask"].any()


# ----------------------------------------------------------- seeding, render
def test_same_seed_same_episode_and_reset_continues_the_stream():
    def run(seed_first: int) -> list:
        env = HanabiEnv(**TWO_COLOURS)
        out = [play_episode(env, random_choice(np.random.default_rng(5)), seed=seed_first)]
        out.append(play_episode(env, random_choice(np.random.default_rng(6)), seed=None))
        return [(r["trajectory"], dict(r["rewards"]), r["score"]) for r in out]

    first, second = run(11), run(11)
    assert first == second
    assert first[0] != first[1]  # unseeded reset moved on in the stream
    assert run(12)[0][0] != first[0][0]


def test_random_start_player_randomises_the_first_seat():
    env = HanabiEnv()
    starts = set()
    for s in range(40):
        env.reset(seed=s)
        starts.add(env.agent_selection)
    assert starts == {"player_0", "player_1"}
    fixed = HanabiEnv(random_start_player=False)
    for s in range(10):
        fixed.reset(seed=s)
        assert fixed.agent_selection == "player_0"


def test_render_ansi_shows_the_state():
    env = HanabiEnv(render_mode="ansi")
    env.reset(seed=0)
    text = env.render()
    assert "Life tokens: 3" in text and "Info tokens: 3" in text and env.agent_selection in text
    quiet = HanabiEnv()
    quiet.reset(seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert quiet.render() is None


def test_move_ids_dataclass_is_config_only():
    ids = HanabiMoveIds(colors=1, ranks=5, players=2, hand_size=2)
    got = (ids.num_moves, ids.discard(1), ids.play(0), ids.reveal_color(1, 0), ids.reveal_rank(1, 4))
    assert got == (10, 1, 2, 4, 9)


def test_an_old_state_survives_later_resets_and_close():
    env = HanabiEnv()
    env.reset(seed=0)
    old, text = env.state, str(env.state)
    for s in range(1, 20):
        env.reset(seed=s)
    env.close()
    assert str(old) == text and old.observation(0).fireworks() == [0]
    env.reset(seed=0)
    assert str(env.state) == text
