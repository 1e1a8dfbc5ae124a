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
    out = spread_over_cores(_jobs(3, 3, 3, 3, 3), SEEDS, cpus=2, first_key="seed")
    assert _cut(out) == [("a", [0, 1, 2]), ("b", [0, 1, 2]), ("d", [0, 1, 2]), ("e", [0, 1, 2]), ("c", [0, 1]), ("c", [2])]
    assert [j["seed"] for j in out if j["name"] == "c"] == [0, 2]  # a piece's seed is its first


def test_even_work_is_left_whole_and_in_order() -> None:
    jobs = _jobs(3, 3, 3, 3)
    assert spread_over_cores(jobs, SEEDS, cpus=2, first_key="seed") == jobs
    assert spread_over_cores(jobs, SEEDS, cpus=1, first_key="seed") == jobs
    one_seed_each = _jobs(1, 1, 1)
    assert spread_over_cores(one_seed_each, SEEDS, cpus=2) == one_seed_each  # nothing to split


def test_one_job_fills_every_core() -> None:
    assert _cut(spread_over_cores(_jobs(5), SEEDS, cpus=2, first_key="seed")) == [("a", [0, 1, 2]), ("a", [3, 4])]
    assert _cut(spread_over_cores(_jobs(2), SEEDS, cpus=4, first_key="seed")) == [("a", [0]), ("a", [1])]


def _wall(jobs: list[dict], cpus: int, key: str = SEEDS) -> int:
    """Unit-lengths until `jobs`, started in order on the first free core, are done (as Tune starts trials)."""
    cores = [0] * cpus
    for j in jobs:
        cores[cores.index(min(cores))] += len(j[key])
    return max(cores)


def test_the_blocks_stage_at_five_seeds_ends_two_seed_lengths_sooner() -> None:
    jobs = _jobs(5, 5, 5, 5, 5)
    assert (_wall(jobs, 2), _wall(spread_over_cores(jobs, SEEDS, cpus=2, first_key="seed"), 2)) == (15, 13)


@pytest.mark.parametrize("sizes", [(5, 5, 5, 5, 5), (3, 1, 4, 1, 5), (7,), (2, 2, 2), (6, 4, 10, 8)])
@pytest.mark.parametrize("cpus", [1, 2, 3, 16])
def test_every_seed_once_and_never_slower_than_whole_jobs(sizes: tuple[int, ...], cpus: int) -> None:
    jobs = _jobs(*sizes)
    out = spread_over_cores(jobs, SEEDS, cpus, first_key="seed")
    per_job: dict[str, list[int]] = {}
    for j in out:
        per_job.setdefault(j["name"], []).extend(j[SEEDS])
    assert {k: sorted(v) for k, v in per_job.items()} == {j["name"]: j[SEEDS] for j in jobs}
    assert _wall(out, cpus) <= _wall(jobs, cpus)
    assert _wall(out, cpus) >= -(-sum(sizes) // cpus)  # no schedule beats the even load
    assert len(out) <= len(sizes) + cpus - 1


def test_seven_adaptation_packs_of_thirty_curves_on_two_cores() -> None:
    # The blocks adapt stage at 5 seeds: 7 variants x 30 curves ran as 2, 2, 2, 1 packs (120 curve-lengths).
    # Cut at 105 a core, one pack splits in halves of 15; the curves are no seeds, so no "seed" key is set.
    packs = [{"index": i, "curves": [f"c{i}-{k}" for k in range(30)]} for i in range(7)]
    out = spread_over_cores(packs, "curves", cpus=2)
    assert [len(p["curves"]) for p in out] == [30] * 6 + [15, 15] and (_wall(packs, 2, "curves"), _wall(out, 2, "curves")) == (
        120,
        105,
    )
    assert [p["index"] for p in out if len(p["curves"]) == 15] == [3, 3] and all("seed" not in p for p in out)
