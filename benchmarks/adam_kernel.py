"""One learner update with `FusedAdamStep` on torch's fused Adam kernel vs its foreach path, interleaved in one process.

For each game (bandit, blocks, Hanabi), three seeds packed as `train` packs them: one train
batch is sampled, then the learner updates on that same batch `--repeats` times with each
kernel, alternating (foreach, fused, fused, foreach, ...), so drift in the machine's speed
falls on both alike. The foreach path is what `FusedAdamStep` used before 2026-12-03; here it
is reached by swapping the module's `adam` for one that asks for it (same arguments
otherwise). Prints medians and their ratio; writes `benchmarks/results/adam_kernel.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.adam_kernel [--repeats 8] [--games bandit blocks hanabi]
"""

from __future__ import annotations

import argparse
import functools
from pathlib import Path
from typing import Any

import pandas as pd
import ray

import rllib_conv.learners.packed.fused_step as fused_step
from benchmarks._common import median_seconds, write_result
from benchmarks.train_throughput import fixed_update, ours, population_of

KERNELS = ("foreach", "fused")


def _adam_with(kernel: dict[str, str]) -> Any:
    """torch's functional `adam`, on the kernel `kernel["now"]` names."""
    real = fused_step.adam

    def adam(*args: Any, **kwargs: Any) -> Any:
        if kernel["now"] == "foreach":
            kwargs.pop("fused", None)
            kwargs["foreach"] = True
        return real(*args, **kwargs)

    return adam


def update_times(population: str, repeats: int, kernel: dict[str, str]) -> dict[str, float]:
    """Median seconds of one learner update per kernel, on one fixed train batch of 3 packed seeds."""
    algo = ours(population, 3).build_algo()
    try:
        algo.train()  # warm-up: optimizer states exist
        update = fixed_update(algo, algo.env_runner.sample())

        def update_with(name: str) -> Any:
            kernel["now"] = name
            return update()

        return median_seconds({name: functools.partial(update_with, name) for name in KERNELS}, repeats)
    finally:
        algo.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=8, help="updates per kernel")
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks", "hanabi"], choices=["bandit", "blocks", "hanabi"])
    args = parser.parse_args()
    kernel = {"now": "fused"}
    fused_step.adam = _adam_with(kernel)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    tmp = Path(__file__).resolve().parent / "results"
    rows = []
    try:
        for game in args.games:
            t = update_times(population_of(game, tmp), args.repeats, kernel)
            rows.append(
                {
                    "env": game,
                    "foreach_ms": 1e3 * t["foreach"],
                    "fused_ms": 1e3 * t["fused"],
                    "foreach/fused": t["foreach"] / t["fused"],
                }
            )
            print(pd.DataFrame(rows).to_string(index=False, float_format="{:.2f}".format), flush=True)
    finally:
        (tmp / "blocks-perm4.json").unlink(missing_ok=True)
        ray.shutdown()
    print(f"wrote {write_result('adam_kernel', {'repeats': args.repeats, 'rows': rows})}")


if __name__ == "__main__":
    main()
