"""How far ego training is from the machine's arithmetic: FLOPs per env step, the speed they run at, each plan's floor.

For each game, `ours` with 3 seeds packed as `train` packs them (paper hyperparameters;
Hanabi against its scripted partners, whose moves need no network): one iteration's
sampling and its learner update are counted with torch's `FlopCounterMode` (matrix
products, forward and backward) and timed (medians over `--repeats`, alternating, on one
fixed batch for the update). Beside them, the machine's own speed at the same arithmetic:
one core's float32 batched matrix product at the learner's largest layer (`peak`: the
replicas x minibatch rows x hidden units of its hidden-to-hidden layers), the best the
update could run at.

The floor of a plan's ego training is its egos' env steps x (sampling + learning FLOPs per
env step) / (cores x peak): what no change to the training loop beats without changing the
networks, the epochs or the budgets. It counts ours' FLOPs for every method of the plan
and leaves out the partners' networks (self-play partners act through networks as large as
the ego's task module), self-play, adaptation and evaluation: a lower bound of the stage,
and of the plan. Writes `benchmarks/results/flop_floor.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.flop_floor [--repeats 5] [--games bandit blocks hanabi]
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import pandas as pd
import ray
import torch
from torch.utils.flop_counter import FlopCounterMode

from benchmarks._common import median_seconds, write_result
from benchmarks.train_throughput import fixed_update, ours, population_of
from rllib_conv import envs
from rllib_conv.pipelines.plans import plan_for
from rllib_conv.training.replica_steps import replica_env_steps

SEEDS = 3  # replicas per trial, as `train` packs a 3-seed experiment
TARGET_MINUTES = {"bandit": 15, "blocks": 60, "hanabi": 30}  # issue 22: the whole plan's wall time


def flops(call: Any) -> tuple[int, Any]:
    """(FLOPs of the matrix products `call()` runs, forward and backward; its return value)."""
    counter = FlopCounterMode(display=False)
    with counter:
        out = call()
    return counter.get_total_flops(), out


def peak_gflops(rows: int, hidden: int, repeats: int = 20) -> float:
    """One core's float32 GFLOP/s on `SEEDS` stacked [rows, hidden] x [hidden, hidden] products (the learner's largest layer)."""
    a, b = torch.randn(SEEDS, rows, hidden), torch.randn(SEEDS, hidden, hidden)
    seconds = median_seconds({"bmm": lambda: torch.bmm(a, b)}, repeats)["bmm"]
    return 2 * SEEDS * rows * hidden * hidden / seconds / 1e9


def plan_ego_steps(game: str, seeds: int = 3) -> int:
    """Env steps of every ego the full plan of `game` trains (each population's methods, then the self-play methods)."""
    plan = plan_for(game, seeds=seeds)
    default = envs.game(game).training_defaults().timesteps
    steps = sum(
        len(variants) * plan.population_overrides.get(population, {}).get("run", {}).get("timesteps", default)
        for population, variants in plan.populations.items()
    )
    steps += len(plan.selfplay) * len(plan.selfplay_methods) * default
    return steps * len(plan.seeds)


def measure(game: str, repeats: int, folder: Path) -> dict[str, Any]:
    """FLOPs per env step and achieved GFLOP/s of one iteration's sampling and learner update for `game`."""
    config = ours(population_of(game, folder), SEEDS)
    algo = config.build_algo()
    try:
        before = algo.train()  # warm-up: optimizer states exist, the env runner's weights are set
        after = algo.train()
        steps = sum(replica_env_steps(after, r) - replica_env_steps(before, r) for r in range(SEEDS))
        runner = algo.env_runner
        sample_flops, episodes = flops(runner.sample)
        update = fixed_update(algo, episodes)
        update_flops, _ = flops(update)
        seconds = median_seconds({"sample": runner.sample, "update": update}, repeats)
    finally:
        algo.stop()
    hidden = envs.game(game).training_defaults().hidden
    peak = peak_gflops(config.minibatch_size, hidden)
    per_step = (sample_flops + update_flops) / steps
    row = {
        "env": game,
        "env_steps_per_iteration": steps,
        "sample_mflop_per_step": sample_flops / steps / 1e6,
        "update_mflop_per_step": update_flops / steps / 1e6,
        "sample_gflops": sample_flops / seconds["sample"] / 1e9,
        "update_gflops": update_flops / seconds["update"] / 1e9,
        "peak_gflops": peak,
        "update_at_peak": update_flops / seconds["update"] / 1e9 / peak,
    }
    plan_steps = plan_ego_steps(game)
    cores = int(ray.cluster_resources().get("CPU", 1))
    row.update(
        {
            "plan_ego_steps": plan_steps,
            "plan_train_floor_min": plan_steps * per_step / (cores * peak * 1e9) / 60,
            "plan_target_min": TARGET_MINUTES[game],
            "trial_steps_per_s_floor": peak * 1e9 / per_step,
        }
    )
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed calls of each of sampling and the update")
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks", "hanabi"], choices=["bandit", "blocks", "hanabi"])
    args = parser.parse_args()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    folder = Path(__file__).resolve().parent / "results"
    rows = []
    try:
        for game in args.games:
            rows.append(measure(game, args.repeats, folder))
            print(pd.DataFrame(rows).to_string(index=False, float_format="{:.3g}".format), flush=True)
    finally:
        (folder / "blocks-perm4.json").unlink(missing_ok=True)
        ray.shutdown()
    print(f"wrote {write_result('flop_floor', {'seeds_per_trial': SEEDS, 'repeats': args.repeats, 'rows': rows})}")


if __name__ == "__main__":
    main()
