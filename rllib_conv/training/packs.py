"""Packs: how a stage's units (adaptation curves, zero-shot egos) are shared out into trials.

Units that can be replicas of one algorithm (the same `packing_key`) may share a trial;
bigger packs pay the env-runner and learner overheads fewer times, but a stage needs at
least as many trials as the cluster has CPUs, or cores idle. `packs` makes packs of at most
`max_pack` units and of about `total / cpus` units, so a small stage still fills every core.
"""

from __future__ import annotations

import math
import os
from collections import defaultdict
from collections.abc import Callable, Hashable
from pathlib import Path
from typing import Any, TypeVar

import pandas as pd
import ray

from rllib_conv.training.tuning import init_ray, trial_job

T = TypeVar("T")


def packs(units: list[T], key: Callable[[T], Hashable], cpus: int, max_pack: int, stage_units: int | None = None) -> list[list[T]]:
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


def cluster_cpus(address: str | None = None) -> int:
    """The CPUs of the Ray cluster at `address` (started locally without one)."""
    init_ray(address)
    return int(ray.cluster_resources().get("CPU", os.cpu_count() or 1))


def write_tables(results: Any, cfgs: list[Any], file: str, columns: list[str], order: list[str], out: Path, what: str) -> dict[str, pd.DataFrame]:
    """Gather the packs' tables (`file` in each trial folder) of a stage's Tune `results` into one CSV per config; return them by name.

    Every trial's config is a job with the `index` of its config in `cfgs`. A config whose
    packs all finished gets `out/<name>.csv` (written whole, then moved into place); one with
    a failed pack gets none, and RuntimeError names them after the others are written.
    """
    parts: list[list[pd.DataFrame]] = [[] for _ in cfgs]
    failed = [0] * len(cfgs)
    for result in results:
        index, path = trial_job(result.config)["index"], Path(result.path) / file
        if result.error or not path.is_file():
            failed[index] += 1
        else:
            parts[index].append(pd.read_csv(path)[columns])
    out.mkdir(parents=True, exist_ok=True)
    tables = {}
    for cfg, frames, errors in zip(cfgs, parts, failed):
        if errors:  # no CSV: a config's CSV means all its rows are in it
            continue
        table = pd.concat(frames, ignore_index=True).sort_values(order, kind="stable", ignore_index=True)
        tmp = out / f".{cfg.name}.csv.tmp"
        table.to_csv(tmp, index=False)
        tmp.replace(out / f"{cfg.name}.csv")
        tables[cfg.name] = table
    if any(failed):
        unfinished = [c.name for c, n in zip(cfgs, failed) if n]
        raise RuntimeError(f"{sum(failed)} {what} pack(s) failed, so {unfinished} wrote no CSV; run again to retry them (finished packs are kept)")
    return tables
