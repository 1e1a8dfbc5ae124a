"""Packs: how a stage's units (adaptation curves, zero-shot egos) are shared out into trials.

Units that can be replicas of one algorithm (the same `packing_key`) may share a trial;
bigger packs pay the env-runner and learner overheads fewer times, but a stage needs at
least as many trials as the cluster has CPUs, or cores idle. `packs` makes packs of at most
`max_pack` units and of about `total / cpus` units, so a small stage still fills every core;
`spread_over_cores` then cuts a stage's trials so none is left alone at the end. The stage
runner (`stage`) does both for every stage pipeline.
"""

from __future__ import annotations

import math
import os
from collections import defaultdict
from collections.abc import Callable, Hashable
from typing import Any, TypeVar

import ray

from rllib_conv.training.tuning import init_ray

T = TypeVar("T")


def packs(
    units: list[T], key: Callable[[T], Hashable], cpus: int, max_pack: int, stage_units: int | None = None
) -> list[list[T]]:
    """`units` split into packs of equal `key`, each of at most `max_pack` and about `stage_units / cpus` units.

    `stage_units` (default `len(units)`) counts the units of the whole stage these are part
    of: every core needs a pack, not every part of the stage. A group of equal key is split
    into packs of nearly equal size (every n-th unit), in the order the units came.
    """
    groups: dict[Hashable, list[T]] = defaultdict(list)
    for unit in units:
        groups[key(unit)].append(unit)
    size = max(1, min(max_pack, math.ceil((stage_units or len(units)) / max(1, cpus))))
    out = []
    for group in groups.values():
        n = math.ceil(len(group) / size)
        out += [group[i::n] for i in range(n)]
    return out


def spread_over_cores(
    jobs: list[dict[str, Any]], units_key: str, cpus: int, first_key: str | None = None
) -> list[dict[str, Any]]:
    """`jobs` (trials, each running the list of equal-cost units under `units_key` together), cut and ordered so they keep `cpus` cores busy.

    Five jobs of 3 seeds on 2 cores run 2, 2, then 1 trial with a core idle: 9 unit-lengths
    of wall time. Cut by McNaughton's wrap-around rule (fill each core to ceil(units / cpus)
    in job order, a job crossing the line split in two; at most `cpus - 1` splits) they run
    as 3, 3, 3, 3, 2 and 1 units: 8. Tune starts trials in order as cores free up, so the
    cut is kept only where that order ends sooner than the whole jobs, as given or longest
    first; otherwise those are returned. A piece keeps its job's other keys, with
    `first_key` (if given) set to its own first unit.
    """
    load = max(1, math.ceil(sum(len(job[units_key]) for job in jobs) / max(1, cpus)))
    pieces, room = [], load
    for job in jobs:
        units = list(job[units_key])
        while units:
            take, units = units[:room], units[room:]
            piece = {**job, units_key: take, **({first_key: take[0]} if first_key else {})}
            pieces.append(job if len(take) == len(job[units_key]) else piece)
            room = room - len(take) or load

    def longest_first(some: list[dict[str, Any]]) -> list[dict[str, Any]]:
        return sorted(some, key=lambda job: -len(job[units_key]))

    candidates = [jobs, longest_first(jobs), longest_first(pieces)]
    return min(candidates, key=lambda js: _wall(js, units_key, cpus))  # the first of the fastest: no cut unless it pays


def _wall(jobs: list[dict[str, Any]], units_key: str, cpus: int) -> int:
    """Unit-lengths until `jobs`, started in order on the first free of `cpus` cores, are all done."""
    cores = [0] * max(1, cpus)
    for job in jobs:
        cores[cores.index(min(cores))] += len(job[units_key])
    return max(cores)


def cluster_cpus(address: str | None = None) -> int:
    """The CPUs of the Ray cluster at `address` (started locally without one)."""
    init_ray(address)
    return int(ray.cluster_resources().get("CPU", os.cpu_count() or 1))
