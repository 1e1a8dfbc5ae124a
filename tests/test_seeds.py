"""Known answers for `rllib_conv.common.seeds`: the seeds every run has always drawn, pinned.

The numbers were computed with the formulas the call sites used before the module
existed (`(s * 1_000_003 + crc32(name)) % 2**32`, `own_seed + 1` / `+ 2`, `seed * 1000 + i`,
`(s * 1_000_003 + offset) % (2**31 - 1)`, `seed + 7919 * i`, `seed + 1000 * i`,
`seed + 1_000_000`, `seed + pair`, `seed + 1 + i`); a change here changes every result.
"""

from __future__ import annotations

import numpy as np
import pytest

from rllib_conv.common import seeds


@pytest.mark.parametrize(
    ("seed", "name", "expected"),
    [(0, "task", 1384045349), (7, "task", 1391045370), (123456789, "task", 4003459492), (2, "mapping", 1241821456)],
)
def test_a_named_stream_has_its_known_seed(seed: int, name: str, expected: int) -> None:
    assert seeds.stream_seed(seed, name) == expected


def test_sampling_and_shuffling_draw_from_the_seed_shifted_by_one_and_two() -> None:
    assert seeds.sampling_seed(0) == 1224399773 == seeds.stream_seed(1, "explore")
    assert seeds.sampling_seed(5) == 1229399788
    assert seeds.shuffle_seed(0, "ego_p0") == 3486046235 == seeds.stream_seed(2, "ego_p0")
    assert seeds.shuffle_seed(3, "ego_p0") == 3489046244
    # The shift keeps a module's shuffling apart from its initial weights (same name, same seed).
    assert seeds.shuffle_seed(0, "ego_p0") != seeds.stream_seed(0, "ego_p0")
    # A seat's own sampling (pairs trained together, MEP): stream of its module ID from seed + 1.
    assert seeds.module_sampling_seed(0, "seat@player_0") == 2677621752 == seeds.stream_seed(1, "seat@player_0")
    assert seeds.module_sampling_seed(3, "seat@player_0") == 2680621761
    assert seeds.module_sampling_seed(0, "seat@player_0") != seeds.stream_seed(0, "seat@player_0")


def test_game_seeds_are_the_replica_seed_mixed_with_the_offset() -> None:
    assert [seeds.game_seed(0, 0), seeds.game_seed(3, 4), seeds.game_seed(4, 3), seeds.game_seed(10**9, 17)] == [
        0,
        3000013,
        4000015,
        1469970703,
    ]


def test_counted_and_set_apart_streams() -> None:
    assert seeds.partner_seed(3, 2) == 3002
    assert seeds.seat_seed(5, 2) == 15843
    assert seeds.series_seed(5, 3) == 3005
    assert seeds.pick_seed(4) == 1_000_004
    assert seeds.pair_seed(10, 3) == 13
    assert seeds.member_seed(10, 0) == 11
    assert [seeds.population_seed(7, p) for p in range(3)] == [7, 10_007, 20_007]


def test_seeds_are_plain_ints_in_range_whatever_integer_type_comes_in() -> None:
    for value in (seeds.stream_seed(np.int64(9), "x"), seeds.game_seed(np.int32(9), 1), seeds.partner_seed(np.int64(1), 0)):
        assert type(value) is int
    assert 0 <= seeds.stream_seed(-5, "task") < 2**32 and 0 <= seeds.game_seed(-5, 0) < 2**31 - 1
