"""Run one slice of a `reproduce` plan with whichever rllib_conv is on the path (the benchmark runs it for two commits).

    python benchmarks/_reproduce_slice.py GAME OUT --populations P ... [--methods M ...] [--train-steps N] [--seeds S] [--no-zeroshot]

`reproduce_walltime` runs it by its file path in the compared code's folder, so it imports
nothing from `benchmarks`. Uses only what the code before and after the speed work both have: `plan_for`, `narrow` and
`Reproduction` importable from `rllib_conv.pipelines.reproduce`. Prints one JSON line: the
wall seconds of the whole slice and of each stage.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from rllib_conv.pipelines.reproduce import Reproduction, narrow, plan_for


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("game")
    p.add_argument("out")
    p.add_argument("--populations", nargs="+", required=True)
    p.add_argument("--methods", nargs="+")
    p.add_argument("--train-steps", type=int)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--no-zeroshot", action="store_true")
    args = p.parse_args()
    plan = narrow(plan_for(args.game, args.seeds, False, args.train_steps), args.populations, args.methods)
    if args.no_zeroshot:
        plan.zeroshot_populations = []
    start = time.perf_counter()
    stages = Reproduction(plan, Path(args.out) / args.game, log=lambda line: print(line, flush=True)).run()
    print("SLICE " + json.dumps({"wall_s": time.perf_counter() - start, "stages": stages}), flush=True)


if __name__ == "__main__":
    main()
