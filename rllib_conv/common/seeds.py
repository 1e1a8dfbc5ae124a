"""Every seed derived from a run's seed, by one rule written down here.

A trained ego (one replica of a trial), a self-play pair or an adaptation config has one
integer seed `s` (its config's `seed`). Everything random it does draws from a stream of
its own, and each stream's seed is derived from `s` here, never by arithmetic at the call
site:

- **Named streams.** `stream_seed(s, name) = (s * 1_000_003 + crc32(name)) mod 2**32`: a
  module's initial weights (`name` its module ID), a partner module's actions, the partner
  schedule (`"mapping"`), a reset layer (`"task_logits_reset"`). `crc32`, not `hash`, so
  every process derives the same number; the prime multiplier keeps the seeds of runs
  `s` and `s + 1` apart for every name.
- **Shifted streams.** A stream that is keyed by a module ID already used for that module's
  initial weights draws from `s + offset` instead, so the two never coincide:
  `s + 1` for the env runners' action sampling (`sampling_seed`; per module, for the seats
  of pairs trained together, `module_sampling_seed`), `s + 2` for the learner's minibatch
  shuffling (`shuffle_seed`).
- **Game seeds.** Sub-environment `offset` of a replica seeded `s` resets with
  `(s * 1_000_003 + offset) mod (2**31 - 1)` (`game_seed`), so replicas packed into one
  env never share a game.
- **Counted streams.** Where one seed feeds a numbered series: the i-th fixed partner of an
  unpacked ego `s * 1000 + i` (`partner_seed`); the i-th seat of an episode series
  `s + 7919 * i` (`seat_seed`); the i-th training partner's states for the marginals
  `s + 1000 * i` (`series_seed`); episode `e` of a series `s + e`.
- **Set-apart streams.** Head-picking episodes in adaptation use `s + 1_000_000`
  (`pick_seed`), far from the evaluation episodes' `s + iteration`.
- **Pairs and members.** Self-play pair k of a config seeded `s` is seeded `s + k`
  (`pair_seed`); population p of a plan's self-play entry with several independently trained
  populations is seeded `s + 10_000 * p` (`population_seed`: no two populations share a pair
  seed while a population has fewer than 10 000 pairs, and population 0 keeps `s`); the i-th player inside a composite player seeded `s` (the convention
  posterior's heads) `s + 1 + i` (`member_seed`).

These are the numbers the library has always used: changing one changes every result, so
`tests/test_seeds.py` pins each with a known answer.
"""

from __future__ import annotations

import zlib

SEED_PRIME = 1_000_003  # the multiplier of every derived seed: runs s and s + 1 stay apart
SAMPLING_OFFSET = 1  # a replica's action-sampling stream draws from s + 1
SHUFFLE_OFFSET = 2  # a replica's minibatch-shuffling streams draw from s + 2
PARTNER_STRIDE = 1000  # the fixed partners of an unpacked ego: s * 1000 + i
SEAT_STRIDE = 7919  # a prime: the seats of an episode series, s + 7919 * i
SERIES_STRIDE = 1000  # per-partner episode series (the marginals' states): s + 1000 * i
POPULATION_STRIDE = 10_000  # independently trained self-play populations: s + 10_000 * p
PICK_SEED_OFFSET = 1_000_000  # head-picking episodes, apart from the evaluation episodes (s + iteration)


def stream_seed(seed: int, name: str) -> int:
    """The seed of stream `name` (a module ID or a stream's name) of a run seeded `seed`; the same in every process."""
    return (int(seed) * SEED_PRIME + zlib.crc32(name.encode())) % (2**32)


def sampling_seed(seed: int) -> int:
    """The seed of a replica's action sampling in the env runners (stream "explore" of `seed + 1`)."""
    return stream_seed(int(seed) + SAMPLING_OFFSET, "explore")


def module_sampling_seed(seed: int, module_id: str) -> int:
    """The seed of module `module_id`'s own action sampling in a run seeded `seed` (stream `module_id` of `seed + 1`)."""
    return stream_seed(int(seed) + SAMPLING_OFFSET, module_id)


def shuffle_seed(seed: int, module_id: str) -> int:
    """The seed of module `module_id`'s minibatch shuffling in a replica seeded `seed` (stream `module_id` of `seed + 2`)."""
    return stream_seed(int(seed) + SHUFFLE_OFFSET, module_id)


def game_seed(seed: int, offset: int) -> int:
    """The game seed of sub-environment `offset` of a replica seeded `seed` (independent of other replicas)."""
    return (int(seed) * SEED_PRIME + int(offset)) % (2**31 - 1)


def partner_seed(seed: int, index: int) -> int:
    """The seed of the `index`-th fixed partner of an unpacked ego seeded `seed`."""
    return int(seed) * PARTNER_STRIDE + int(index)


def seat_seed(seed: int, index: int) -> int:
    """The seed of the player in the `index`-th seat of an episode series seeded `seed`."""
    return int(seed) + SEAT_STRIDE * int(index)


def series_seed(seed: int, index: int) -> int:
    """The first episode seed of the `index`-th of several episode series run from one seed (one per partner)."""
    return int(seed) + SERIES_STRIDE * int(index)


def pair_seed(seed: int, pair: int) -> int:
    """The seed of self-play pair `pair` of a config seeded `seed`."""
    return int(seed) + int(pair)


def population_seed(seed: int, population: int) -> int:
    """The seed of the `population`-th of several independently trained self-play populations of one config seeded `seed`."""
    return int(seed) + POPULATION_STRIDE * int(population)


def member_seed(seed: int, index: int) -> int:
    """The seed of the `index`-th player inside a composite player seeded `seed` (the convention posterior's heads)."""
    return int(seed) + 1 + int(index)


def pick_seed(seed: int) -> int:
    """The first episode seed of adaptation's head-picking episodes (`seed` the adapt config's)."""
    return int(seed) + PICK_SEED_OFFSET
