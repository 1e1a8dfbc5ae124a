"""Human proxies (Carroll et al. 2019): how each stay rule clones people, then BC and H_proxy on every layout.

Two parts, one run, one training job at a time:

1. `stay`: cramped_room, 3 seeds, each stay rule of `training.behaviour_cloning.STAY_RULES`,
   trained into a throwaway cache (the real proxies are not touched): held-out accuracy (on
   every row and on the non-STAY rows) and the sparse returns of BC + BC and BC + H_proxy,
   beside the logged human pairs' return per 400 steps.
2. `layouts`: `pipelines.human_proxies.run` with the default rule on the chosen layouts and
   seeds, into the cache (`--cache`, else `$RLLIB_CONV_CACHE/overcooked`, else
   `~/.cache/rllib-conv/overcooked`): the proxies the built-in populations name.

Needs the human data converted in the cache (`rllib-conv human-data overcooked`). Writes only
numbers to `benchmarks/results/human_proxies.json`, never data or weights.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.human_proxies [--layouts ...] [--seeds 0 1 2] [--cache DIR]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import pandas as pd
import torch

from benchmarks._common import write_result
from rllib_conv.envs.overcooked.human_data import LAYOUTS, cache_folder
from rllib_conv.pipelines import human_proxies
from rllib_conv.training.behaviour_cloning import STAY_RULES, BCSettings

# The measured RLlib offline BC attempt (see training/behaviour_cloning.py's docstring): a
# hand-run script on cramped_room's non-STAY train rows, RLlib 2.60, BCConfig + offline_data.
RLLIB_BC = {
    "num_cpus_2": "no progress in 60 s: Ray Data's OfflinePreLearner actor pool waited for 2 free CPUs",
    "num_cpus_4_build_s": 9.3,
    "num_cpus_4_first_iteration_s": 15.8,
    "num_cpus_4_iteration_s_63_batches_of_64": 0.2,
}


def summarise(table: pd.DataFrame, by: str) -> list[dict]:
    """Mean and min/max over seeds of every numeric column, per value of `by`."""
    numeric = table.drop(columns=["seed"]).select_dtypes("number").columns
    out = []
    for key, part in table.groupby(by, sort=False):
        row = {by: key, "seeds": int(len(part))}
        for column in numeric:
            row[column] = round(float(part[column].mean()), 4)
            row[f"{column}_range"] = [round(float(part[column].min()), 4), round(float(part[column].max()), 4)]
        out.append(row)
    return out


def stay_comparison(cache: Path, seeds: list[int], episodes: int) -> tuple[pd.DataFrame, float]:
    """Every stay rule on cramped_room, trained into a temporary cache that borrows the real cache's trajectories."""
    started = time.perf_counter()
    tables = []
    for rule in STAY_RULES:
        with tempfile.TemporaryDirectory(prefix="proxies-stay-") as tmp:
            (Path(tmp) / "trajectories").symlink_to(cache / "trajectories")
            tables.append(human_proxies.run(["cramped_room"], seeds, tmp, BCSettings(stay=rule), episodes))
    return pd.concat(tables, ignore_index=True), time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layouts", nargs="+", default=list(LAYOUTS), choices=LAYOUTS)
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--cache", default=None)
    parser.add_argument("--skip-stay", action="store_true", help="only the layouts part")
    args = parser.parse_args()
    torch.set_num_threads(int(os.environ.get("OMP_NUM_THREADS", "1")))
    cache = cache_folder(args.cache)
    result: dict = {"episodes": args.episodes, "horizon": 400, "reward": "sparse", "rllib_bc": RLLIB_BC}
    if not args.skip_stay:
        stay, seconds = stay_comparison(cache, args.seeds, args.episodes)
        result["stay"] = {"wall_s": round(seconds, 1), "by_rule": summarise(stay, "stay"), "rows": stay.to_dict("records")}
        print(stay.groupby("stay").mean(numeric_only=True).T.to_string())
    started = time.perf_counter()
    table = human_proxies.run(args.layouts, args.seeds, args.cache, BCSettings(), args.episodes, progress=True)
    result["layouts"] = {
        "stay": BCSettings().stay,
        "wall_s": round(time.perf_counter() - started, 1),
        "by_layout": summarise(table, "layout"),
        "rows": table.to_dict("records"),
    }
    print(table.groupby("layout").mean(numeric_only=True).T.to_string())
    print("wrote", write_result("human_proxies", result))


if __name__ == "__main__":
    main()
