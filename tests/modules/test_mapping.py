"""PartnerMapping: one partner per episode, in turn; ego to its head, partner to its module."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from rllib_conv.modules import AGG_HEAD_ID, PartnerMapping


def ep(i: int) -> SimpleNamespace:
    return SimpleNamespace(id_=f"episode-{i}")


def test_round_robin_and_consistent_within_an_episode() -> None:
    m = PartnerMapping(["a", "b", "c"], "player_0", "player_1")
    got = []
    for i in range(7):
        got.append((m("player_1", ep(i)), m("player_0", ep(i))))
    assert got == [
        ("partner@a", "ego@a"),
        ("partner@b", "ego@b"),
        ("partner@c", "ego@c"),
        ("partner@a", "ego@a"),
        ("partner@b", "ego@b"),
        ("partner@c", "ego@c"),
        ("partner@a", "ego@a"),
    ]


def test_shared_head_for_agg_and_unknown_agents() -> None:
    m = PartnerMapping(["a", "b"], "player_0", "player_1", shared_head=True)
    assert m("player_0", ep(0)) == AGG_HEAD_ID and m("player_1", ep(0)) == "partner@a"
    with pytest.raises(ValueError, match="neither the ego"):
        m("player_2", ep(0))
    with pytest.raises(ValueError, match="at least one partner"):
        PartnerMapping([], "player_0", "player_1")
