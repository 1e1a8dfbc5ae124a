"""The compiled minibatch step: one learner update with the stacked ego's minibatch loss under `torch.compile`, against eager, and what compiling costs.

    OMP_NUM_THREADS=1 python -m benchmarks.compiled_step [--games bandit blocks] [--replicas 3] [--repeats 5] [--rounds 2] [--name NAME]

Issue 49's lever "optionally the compiled step": `FusedUpdateLearner._minibatch_loss`
(gathers, forward, PPO loss and the regulariser of one minibatch) compiled by inductor as one
graph, forward and backward; clipping and the fused Adam stay eager. For each case (a
population and a method, 3 seeds packed as `train` packs them) every measurement is a fresh
process: `eager`; `cold`, compiled with an empty inductor cache (what the first trial of a
shape pays on a fresh machine, CI included); `warm`, compiled again from the cache `cold` left.
Each reports the median update over `--repeats` updates on one fixed batch (after one eager
warm-up iteration) and, compiled, the first update's extra seconds: the compile. The modes
alternate for `--rounds` rounds. `break_even_updates` is the compile's seconds over the
milliseconds an update saves; `updates_per_trial` is how many updates the plan's trial of that
case runs (its env-step budget over the steps of one iteration): compiling pays in a trial only
where the second exceeds the first. Written to `benchmarks/results/<NAME>.json` (default `compiled_step`).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import tempfile
import time
from pathlib import Path

import pandas as pd
import ray
import torch

from benchmarks._common import alternating, run_with_code, write_result
from benchmarks.learner_update import CASES, case_name
from benchmarks.reproduce_walltime import REPO
from benchmarks.train_throughput import fixed_update, population_of
from rllib_conv.training.algorithm import Replica, build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.replica_steps import replica_env_steps

MODES = ("eager", "cold", "warm")


def measure(game: str, case: int, compiled: bool, replicas: int, repeats: int) -> dict[str, float]:
    """One case's median update (ms), its first update's extra seconds and its plan trial's updates, eager or compiled."""
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    population, method, lam = CASES[game][case]
    with tempfile.TemporaryDirectory() as tmp:
        pop = population or population_of(game, Path(tmp))
        exps = [resolve(ExperimentConfig(population=pop, method=method, lam=lam, seed=s)) for s in range(replicas)]
        algo = build_ppo_config([Replica(e) for e in exps]).build_algo()
        try:
            result = algo.train()  # eager warm-up: optimizer states exist, lazy set-up done
            updates = exps[0].exp.run.timesteps / max(1, replica_env_steps(result, 0))
            update = fixed_update(algo, algo.env_runner.sample())
            update()
            learner = algo.learner_group._learner
            if compiled:
                learner._minibatch_loss = torch.compile(learner._minibatch_loss, dynamic=False)
            start = time.perf_counter()
            update()
            first = time.perf_counter() - start
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                update()
                times.append(time.perf_counter() - start)
        finally:
            algo.stop()
    median = statistics.median(times)
    return {"update_ms": 1e3 * median, "compile_s": first - median, "updates_per_trial": updates}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks"], choices=list(CASES))
    parser.add_argument("--replicas", type=int, default=3, help="seeds packed per case")
    parser.add_argument("--repeats", type=int, default=5, help="timed updates per measurement")
    parser.add_argument("--rounds", type=int, default=2, help="measurements of each mode")
    parser.add_argument("--name", default="compiled_step")
    parser.add_argument("--child", nargs=3, metavar=("GAME", "CASE", "MODE"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        game, case, mode = args.child
        print("MS " + json.dumps(measure(game, int(case), mode != "eager", args.replicas, args.repeats)))
        return
    work = Path(tempfile.mkdtemp(prefix="compiled-step-"))
    cases = [(game, i) for game in args.games for i in range(len(CASES[game]))]
    runs: dict[str, dict[str, list[dict[str, float]]]] = {}
    for game, i in cases:
        name = case_name(game, *CASES[game][i])
        runs[name] = {mode: [] for mode in MODES}
        for r, mode in enumerate(alternating(["eager", "compiled"], args.rounds)):
            order = ["eager"] if mode == "eager" else ["cold", "warm"]
            for m in order:
                # A fresh inductor cache per round for `cold`; `warm` reads the one `cold` just filled.
                os.environ["TORCHINDUCTOR_CACHE_DIR"] = str(work / f"{game}-{i}-{r}")
                child = ["--child", game, str(i), m, "--replicas", str(args.replicas), "--repeats", str(args.repeats)]
                runs[name][m].append(json.loads(run_with_code(REPO, "compiled_step", child, "MS")))
    rows = []
    for name, by_mode in runs.items():
        med = {m: {k: statistics.median(r[k] for r in by_mode[m]) for k in by_mode[m][0]} for m in MODES}
        eager, warm = med["eager"]["update_ms"], med["warm"]["update_ms"]
        saved_ms = eager - warm
        rows.append(
            {
                "case": name,
                "eager_ms": eager,
                "compiled_ms": warm,
                "eager/compiled": eager / warm,
                "cold_compile_s": med["cold"]["compile_s"],
                "cached_compile_s": med["warm"]["compile_s"],
                "break_even_updates": med["cold"]["compile_s"] * 1e3 / saved_ms if saved_ms > 0 else float("inf"),
                "updates_per_trial": med["eager"]["updates_per_trial"],
            }
        )
    print(pd.DataFrame(rows).to_string(index=False, float_format="{:.2f}".format), flush=True)
    result = {"replicas": args.replicas, "repeats": args.repeats, "rounds": args.rounds, "torch": torch.__version__}
    print(f"wrote {write_result(args.name, {**result, 'rows': rows, 'runs': runs})}")


if __name__ == "__main__":
    main()
