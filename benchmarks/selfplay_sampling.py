"""A self-play pair's `train()` with the batched runner vs RLlib's episode path, interleaved in one process.

For each game, two algorithms of the same self-play pair (`tune_configs/selfplay_<game>.yaml`,
pair 0), one sampling through `BatchedEnvRunner` and one through RLlib's episodes
(`LeanEnvRunner`, the self-play path before 2026-12-03), take turns at
`train()` (RLlib, batched, batched, RLlib, ...), so drift in the machine's speed falls on
both alike. Gate checks are not part of `train()`. Prints the median seconds per iteration,
the env steps/s and the ratio; writes `benchmarks/results/selfplay_sampling.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.selfplay_sampling [--iterations 6] [--games bandit blocks hanabi]
"""

from __future__ import annotations

import argparse

import pandas as pd
import ray

from benchmarks._common import median_seconds, write_result
from rllib_conv.common import config_files
from rllib_conv.common.resources import config_file
from rllib_conv.pipelines.selfplay import build_selfplay_config
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.training.batched_env_runner import BatchedEnvRunner
from rllib_conv.training.lean_env_runner import LeanEnvRunner

PATHS = {"rllib": LeanEnvRunner, "batched": BatchedEnvRunner}  # name -> env runner class


def iteration_times(game: str, iterations: int) -> tuple[dict[str, float], int]:
    """Median seconds of one `train()` per path, and the env steps of one iteration."""
    algos = {}
    try:
        for name, runner in PATHS.items():
            raw = config_files.load(config_file(f"selfplay_{game}.yaml"), [], schema=SelfPlayConfig)
            cfg = SelfPlayConfig.model_validate(raw).resolve()
            algos[name] = build_selfplay_config(cfg).env_runners(env_runner_cls=runner).build_algo()
            algos[name].train()  # warm-up
        return median_seconds({name: algo.train for name, algo in algos.items()}, iterations), cfg.ppo.rollout_per_partner
    finally:
        for algo in algos.values():
            algo.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=6, help="timed train() calls per path")
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks", "hanabi"], choices=["bandit", "blocks", "hanabi"])
    args = parser.parse_args()
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    rows = []
    try:
        for game in args.games:
            t, steps = iteration_times(game, args.iterations)
            rows.append(
                {
                    "env": game,
                    "env_steps_per_iteration": steps,
                    "rllib_s": t["rllib"],
                    "batched_s": t["batched"],
                    "rllib_steps_per_s": steps / t["rllib"],
                    "batched_steps_per_s": steps / t["batched"],
                    "rllib/batched": t["rllib"] / t["batched"],
                }
            )
            print(pd.DataFrame(rows).to_string(index=False, float_format="{:.3f}".format), flush=True)
    finally:
        ray.shutdown()
    print(f"wrote {write_result('selfplay_sampling', {'iterations': args.iterations, 'rows': rows})}")


if __name__ == "__main__":
    main()
