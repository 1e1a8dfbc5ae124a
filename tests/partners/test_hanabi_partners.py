"""Tests for the scripted Hanabi partners (random legal and the hint/play rule player)."""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv.envs.hanabi import (
    HanabiEnv,
    HanabiMoveIds,
    card_knowledge_layout,
    decode_card_knowledge,
)
from rllib_conv.partners.base import Partner
from rllib_conv.partners.hanabi import HanabiRulePartner, RandomLegalPartner
from rllib_conv.partners.kinds import kinds, partner_from_spec

IDS = HanabiMoveIds(colors=1, ranks=5, players=2, hand_size=2)

# Measured with `selfplay_scores(..., episodes=500, first_seed=0)` below: random 0.518
# (0.45..0.59 over six disjoint 500-episode blocks, mean 0.51), rule 3.824 (3.79..3.83).
RANDOM_RANGE = (0.45, 0.62)
RULE_MIN, RULE_MARGIN = 3.4, 2.5


def selfplay_scores(partners: list[Partner], episodes: int, config: dict | None = None, first_seed: int = 0) -> np.ndarray:
    """Final scores of `episodes` games; game e uses env seed e and partner seeds derived from it."""
    env = HanabiEnv(**(config or {}))
    n = env.config["players"]
    scores = []
    for e in range(first_seed, first_seed + episodes):
        env.reset(seed=e)
        for i, p in enumerate(partners):
            p.seed(e * n + i + 1)
        total = 0.0
        for agent in env.agent_iter():
            obs, reward, term, trunc, _ = env.last()
            if term or trunc:
                env.step(None)
                continue
            # The env rejects illegal moves, so finishing a game also proves every move was legal.
            env.step(partners[int(agent.rsplit("_", 1)[1])].act(obs["observation"], obs["action_mask"]))
            total += env.rewards[agent]
        assert total == env.state.score()
        scores.append(total)
    return np.array(scores)


def crafted_view(
    *,
    other_hand: list[tuple[int, int]],
    own_knowledge: list[set[tuple[int, int]]],
    own_hinted_ranks: list[int | None],
    fireworks: int,
    information_tokens: int,
    life_tokens: int = 3,
    deck_size: int = 2,
    discards: dict[int, int] | None = None,
) -> np.ndarray:
    """Build a paper-config observation vector by hand (1 colour, so cards are (0, rank))."""
    lay = card_knowledge_layout(1, 5, 2, 2, 3, 3)
    v = np.zeros(lay["card_knowledge"][1], dtype=np.float32)
    for slot, (_, r) in enumerate(other_hand):
        v[lay["hands"][0] + slot * 5 + r] = 1
    v[lay["deck"][0] : lay["deck"][0] + deck_size] = 1
    if fireworks:
        v[lay["fireworks"][0] + fireworks - 1] = 1
    v[lay["information_tokens"][0] : lay["information_tokens"][0] + information_tokens] = 1
    v[lay["life_tokens"][0] : lay["life_tokens"][0] + life_tokens] = 1
    offsets = [0, 3, 5, 7, 9]  # thermometer start per rank: three 1s, two each of 2-4, one 5
    for r, n in (discards or {}).items():
        v[lay["discards"][0] + offsets[r] : lay["discards"][0] + offsets[r] + n] = 1
    per_card = 5 + 1 + 5
    start = lay["card_knowledge"][0]
    for slot, (possible, rank) in enumerate(zip(own_knowledge, own_hinted_ranks)):
        base = start + slot * per_card
        for _, r in possible:
            v[base + r] = 1
        if rank is not None:
            v[base + 6 + rank] = 1
    for slot in range(len(other_hand)):  # the other player knows nothing
        base = start + 2 * per_card + slot * per_card
        v[base : base + 5] = 1
    return v


def mask_of(*ids: int) -> np.ndarray:
    m = np.zeros(IDS.num_moves, dtype=np.int8)
    m[list(ids)] = 1
    return m


ALL = {(0, r) for r in range(5)}


# ------------------------------------------------------------------ random
def test_random_partner_plays_only_legal_moves_and_is_seeded():
    mask = np.array([0, 1, 0, 0, 1, 1, 0], dtype=np.int8)
    a, b = RandomLegalPartner(seed=3), RandomLegalPartner(seed=3)
    first = [a.act(np.zeros(4), mask) for _ in range(50)]
    assert first == [b.act(np.zeros(4), mask) for _ in range(50)]
    assert set(first) == {1, 4, 5}
    a.seed(3)
    assert [a.act(np.zeros(4), mask) for _ in range(50)] == first
    other = RandomLegalPartner(seed=4)
    assert [other.act(np.zeros(4), mask) for _ in range(50)] != first


def test_random_partner_rejects_an_empty_mask():
    with pytest.raises(ValueError, match="no legal action"):
        RandomLegalPartner().act(np.zeros(3), np.zeros(5, dtype=np.int8))


def test_partners_round_trip_through_specs():
    assert {"random_legal", "hanabi_rule"} <= set(kinds())
    for partner in (RandomLegalPartner(name="r", seed=9), HanabiRulePartner(name="h", colors=2)):
        spec = partner.to_spec()
        rebuilt = partner_from_spec(spec)
        assert type(rebuilt) is type(partner) and rebuilt.to_spec() == spec
    assert HanabiRulePartner().params() == {
        "colors": 1,
        "ranks": 5,
        "players": 2,
        "hand_size": 2,
        "max_information_tokens": 3,
        "max_life_tokens": 3,
    }


# -------------------------------------------------------------------- rule
def test_crafted_view_decodes_as_intended():
    v = crafted_view(
        other_hand=[(0, 2), (0, 3)],
        own_knowledge=[{(0, 0)}, ALL],
        own_hinted_ranks=[0, None],
        fireworks=2,
        information_tokens=1,
        discards={0: 1},
    )
    d = decode_card_knowledge(v)
    assert d["hands"] == [[], [(0, 2), (0, 3)]] and d["fireworks"] == [2]
    assert d["information_tokens"] == 1 and d["discard_counts"] == [[1, 0, 0, 0, 0]]
    assert d["own_possible"] == [{(0, 0)}, ALL] and d["knowledge"][0][0]["rank"] == 0


def test_rule_plays_a_card_known_to_be_playable():
    v = crafted_view(
        other_hand=[(0, 3), (0, 4)],
        own_knowledge=[ALL, {(0, 2)}],
        own_hinted_ranks=[None, 2],
        fireworks=2,
        information_tokens=2,
    )
    assert HanabiRulePartner().act(v, mask_of(0, 1, 2, 3, 5, 8, 9)) == IDS.play(1)


def test_rule_deduces_playability_from_visible_cards():
    # Own card could be a 3 or a 4, but both 4s are visible elsewhere: it must be the playable 3.
    v = crafted_view(
        other_hand=[(0, 3), (0, 4)],
        own_knowledge=[{(0, 2), (0, 3)}, ALL],
        own_hinted_ranks=[None, None],
        fireworks=2,
        information_tokens=0,
        discards={3: 1},
    )
    assert HanabiRulePartner().act(v, mask_of(0, 1, 2, 3)) == IDS.play(0)


def test_rule_hints_the_rank_of_a_playable_card():
    v = crafted_view(
        other_hand=[(0, 4), (0, 2)],
        own_knowledge=[ALL, ALL],
        own_hinted_ranks=[None, None],
        fireworks=2,
        information_tokens=1,
    )
    assert HanabiRulePartner().act(v, mask_of(0, 1, 2, 3, 4, 7, 9)) == IDS.reveal_rank(1, 2)


def test_rule_discards_the_least_useful_card():
    # Card 0 was hinted to be a 1, already played: worthless. Card 1 is unknown.
    v = crafted_view(
        other_hand=[(0, 3), (0, 3)],
        own_knowledge=[{(0, 0)}, ALL],
        own_hinted_ranks=[0, None],
        fireworks=2,
        information_tokens=0,
    )
    assert HanabiRulePartner().act(v, mask_of(0, 1, 2, 3)) == IDS.discard(0)
    # Unknown card vs a card known to be the 5 (the last copy): keep the 5.
    v = crafted_view(
        other_hand=[(0, 3), (0, 3)],
        own_knowledge=[{(0, 4)}, ALL],
        own_hinted_ranks=[4, None],
        fireworks=2,
        information_tokens=0,
    )
    assert HanabiRulePartner().act(v, mask_of(0, 1, 2, 3)) == IDS.discard(1)


def test_rule_hints_when_discarding_is_illegal():
    v = crafted_view(
        other_hand=[(0, 4), (0, 3)],
        own_knowledge=[ALL, ALL],
        own_hinted_ranks=[None, None],
        fireworks=0,
        information_tokens=3,
    )
    # Nothing is playable for the other player and tokens are full: an informative hint on its lowest card.
    assert HanabiRulePartner().act(v, mask_of(2, 3, 4, 8, 9)) == IDS.reveal_rank(1, 3)


def test_rule_hint_then_play_in_a_real_game():
    """Seat A sees B's playable 1 and hints it; B then plays exactly that card."""
    env = HanabiEnv()
    rule = HanabiRulePartner()
    for s in range(100):
        env.reset(seed=s)
        me = env.state.cur_player()
        mine, theirs = env.state.player_hands()[me], env.state.player_hands()[1 - me]
        if all(c.rank() != 0 for c in mine) and any(c.rank() == 0 for c in theirs):
            break
    else:
        raise AssertionError("no suitable seed")
    obs = env.observe(env.agent_selection)
    assert rule.act(obs["observation"], obs["action_mask"]) == IDS.reveal_rank(1, 0)
    env.step(IDS.reveal_rank(1, 0))
    obs = env.observe(env.agent_selection)
    move = rule.act(obs["observation"], obs["action_mask"])
    slot = [c.rank() for c in theirs].index(0)
    assert move == IDS.play(slot)
    env.step(move)
    assert env.state.score() == 1


def test_rule_partner_is_deterministic_and_validates_its_inputs():
    env = HanabiEnv()
    env.reset(seed=0)
    obs = env.observe(env.agent_selection)
    assert len({HanabiRulePartner().act(obs["observation"], obs["action_mask"]) for _ in range(5)}) == 1
    with pytest.raises(ValueError, match="length"):
        HanabiRulePartner().act(np.zeros(50), obs["action_mask"])
    with pytest.raises(ValueError, match="action mask"):
        HanabiRulePartner().act(obs["observation"], np.ones(12, dtype=np.int8))
    with pytest.raises(ValueError, match="no legal action"):
        HanabiRulePartner().act(obs["observation"], np.zeros(10, dtype=np.int8))
    with pytest.raises(ValueError, match="colors"):
        HanabiRulePartner(colors=0)
    minimal = HanabiEnv(observation_type=0)
    minimal.reset(seed=0)
    obs = minimal.observe(minimal.agent_selection)
    with pytest.raises(ValueError, match="card-knowledge"):
        HanabiRulePartner().act(obs["observation"], obs["action_mask"])


# --------------------------------------------------------------- self-play
def test_selfplay_scores_random_near_known_value_and_rule_well_above():
    random_scores = selfplay_scores([RandomLegalPartner(), RandomLegalPartner()], episodes=500)
    rule_scores = selfplay_scores([HanabiRulePartner(), HanabiRulePartner()], episodes=500)
    assert RANDOM_RANGE[0] <= random_scores.mean() <= RANDOM_RANGE[1]
    assert rule_scores.mean() >= RULE_MIN
    assert rule_scores.mean() >= random_scores.mean() + RULE_MARGIN
    again = selfplay_scores([HanabiRulePartner(), HanabiRulePartner()], episodes=50)
    assert again.tolist() == rule_scores[:50].tolist()


def test_rule_partner_works_in_a_bigger_game():
    config = {"colors": 2, "players": 3, "hand_size": 3}
    rule = [HanabiRulePartner(**config) for _ in range(3)]
    rand = [RandomLegalPartner(seed=i) for i in range(3)]
    assert selfplay_scores(rule, 40, config).mean() > selfplay_scores(rand, 40, config).mean() + 1.0
