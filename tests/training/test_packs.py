"""How a stage's work is cut into trials so that no core idles (known answers)."""

from __future__ import annotations

import pytest

from rllib_conv.training.packs import spread_over_cores

SEEDS = "replica_seeds"


def _jobs(*sizes: int) -> list[dict]:
    """Jobs named a, b, c, ... training `size` seeds each (seeds 0..size-1)."""
    return [{"name": chr(97 + i), "seed": 0, SEEDS: list(range(n))} for i, n in enumerate(sizes)]


def _cut(jobs: list[dict]) -> list[tuple[str, list[int]]]:
    return [(j["name"], j[SEEDS]) for j in jobs]


def test_five_jobs_of_three_seeds_on_two_cores() -> None:
    # Load ceil(15 / 2) = 8 a core: a, b, c[0:2] on the first; c[2:], d, e on the second.
    out = spread_over_cores(_jobs(3, 3, 3, 3, 3), SEEDS, cpus=2)
    assert _cut(out) == [("a", [0, 1, 2]), ("b", [0, 1, 2]), ("d", [0, 1, 2]), ("e", [0, 1, 2]), ("c", [0, 1]), ("c", [2])]
    assert [j["seed"] for j in out if j["name"] == "c"] == [0, 2]  # a piece's seed is its first


def test_even_work_is_left_whole_and_in_order() -> None:
    jobs = _jobs(3, 3, 3, 3)
    assert spread_over_cores(jobs, SEEDS, cpus=2) == jobs
    assert spread_over_cores(jobs, SEEDS, cpus=1) == jobs
    one_seed_each = _jobs(1, 1, 1)
    assert spread_over_cores(one_seed_each, SEEDS, cpus=2) == one_seed_each  # nothing to split


def test_one_job_fills_every_core() -> None:
    assert _cut(spread_over_cores(_jobs(5), SEEDS, cpus=2)) == [("a", [0, 1, 2]), ("a", [3, 4])]
    assert _cut(spread_over_cores(_jobs(2), SEEDS, cpus=4)) == [("a", [0]), ("a", [1])]


def _wall(jobs: list[dict], cpus: int) -> int:
    """Seed-lengths until `jobs`, started in order on the first free core, are done (as Tune starts trials)."""
    cores = [0] * cpus
    for j in jobs:
        cores[cores.index(min(cores))] += len(j[SEEDS])
    return max(cores)


def test_the_blocks_stage_at_five_seeds_ends_two_seed_lengths_sooner() -> None:
    jobs = _jobs(5, 5, 5, 5, 5)
    assert (_wall(jobs, 2), _wall(spread_over_cores(jobs, SEEDS, cpus=2), 2)) == (15, 13)


@pytest.mark.parametrize("sizes", [(5, 5, 5, 5, 5), (3, 1, 4, 1, 5), (7,), (2, 2, 2), (6, 4, 10, 8)])
@pytest.mark.parametrize("cpus", [1, 2, 3, 16])
def test_every_seed_once_and_never_slower_than_whole_jobs(sizes: tuple[int, ...], cpus: int) -> None:
    jobs = _jobs(*sizes)
    out = spread_over_cores(jobs, SEEDS, cpus)
    per_job: dict[str, list[int]] = {}
    for j in out:
        per_job.setdefault(j["name"], []).extend(j[SEEDS])
    assert {k: sorted(v) for k, v in per_job.items()} == {j["name"]: j[SEEDS] for j in jobs}
    assert _wall(out, cpus) <= _wall(jobs, cpus)
    assert _wall(out, cpus) >= -(-sum(sizes) // cpus)  # no schedule beats the even load
    assert len(out) <= len(sizes) + cpus - 1
