"""A stage of short trials with Tune's worker reuse (`AlgorithmTrainable.reset_config`) and without it, alternating.

The stage is the bandit's self-play population (`tune_configs/selfplay_bandit.yaml`, `--pairs`
pairs, each a Tune trial of ~16 short iterations), trained from an empty folder `--rounds`
times each way, in the order reuse, new workers, new workers, reuse, ..., so drift in the
machine's speed falls on both alike. Without reuse, Tune is asked for `reuse_actors=False` and starts a new worker for
every trial (what it did before 2026-12-03). Prints the wall times,
the workers used and the ratio of medians; writes `benchmarks/results/actor_reuse.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.actor_reuse [--pairs 8] [--rounds 2]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path
from typing import Any

import pandas as pd
import ray
from ray import tune

from benchmarks._common import alternating, write_result
from rllib_conv.common import config_files
from rllib_conv.common.resources import config_file
from rllib_conv.pipelines.selfplay import train_population
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

TUNE_CONFIG = tune.TuneConfig


def _tune_config(reuse: bool) -> Any:
    """`tune.TuneConfig` with `reuse_actors` forced to `reuse` (what `tuning.fit` builds its Tuner with)."""
    return lambda **kwargs: TUNE_CONFIG(**{**kwargs, "reuse_actors": reuse})


def stage(pairs: int, reuse: bool) -> dict:
    """Train a `pairs`-pair bandit self-play population from an empty folder; wall seconds and workers used."""
    tune.TuneConfig = _tune_config(reuse)
    raw = config_files.load_checked(
        config_file("selfplay_bandit.yaml"), [f"train_pairs={pairs}", "test_pairs=0", "name=reuse-bench"], schema=SelfPlayConfig
    )
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        _, report = train_population(raw, out=Path(tmp) / "pops", storage=Path(tmp) / "runs")
        wall = time.perf_counter() - start
        workers = {json.loads(f.read_text().strip().splitlines()[-1])["pid"] for f in Path(tmp, "runs").glob("*/*/result.json")}
    return {"reuse": reuse, "wall_s": wall, "workers": len(workers), "passed": int(report["passed"].sum())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=8, help="self-play pairs (trials) per stage")
    parser.add_argument("--rounds", type=int, default=2, help="stages per way")
    args = parser.parse_args()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    rows = []
    try:
        for reuse in alternating((True, False), args.rounds):
            rows.append(stage(args.pairs, reuse))
            print(pd.DataFrame(rows).to_string(index=False, float_format="{:.1f}".format), flush=True)
    finally:
        tune.TuneConfig = TUNE_CONFIG
        ray.shutdown()
    walls = {way: statistics.median(r["wall_s"] for r in rows if r["reuse"] == way) for way in (True, False)}
    summary = {"reuse_s": walls[True], "new_workers_s": walls[False], "new_workers/reuse": walls[False] / walls[True]}
    print(summary)
    print(f"wrote {write_result('actor_reuse', {'pairs': args.pairs, 'rounds': args.rounds, 'rows': rows, 'summary': summary})}")


if __name__ == "__main__":
    main()
