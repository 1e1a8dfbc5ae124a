"""The adapt stage's set-up in the driver: checking and packing every curve before Tune starts, this code against a baseline.

`reproduce`'s adapt stage checks every curve (`adapt_curve`: the trained ego's config, the
partners' population, the adapter's needs) and computes its packing key before any trial runs.
A 10-seed bandit plan has thousands of curves, and the check used to read and validate the
population manifest once per curve (each read parsing YAML and building every partner: a
trained partner loads its network). This script times that phase on a finished `train` stage
(`reproduce <game> --out OUT` past its train stage) for the curves of `--population` (every
method and adapt variant that adapts to it), in this checkout and, with `--baseline`, in a
worktree of older code (a subprocess with that `PYTHONPATH`), alternating, and prints a table;
writes `benchmarks/results/adapt_setup.json`.

    OMP_NUM_THREADS=1 python -m benchmarks.adapt_setup /work/repro/b10 --game bandit --seeds 10 \\
        --population bandit-s3-selfplay-p1 --baseline /work/wt-bandit --repeats 3
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from benchmarks._common import alternating, write_result
from rllib_conv.common import config_files
from rllib_conv.pipelines.adapt import adapt_curve, adaptation_curves, curve_packing_key
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.plans import plan_for
from rllib_conv.pipelines.reproduce import ARGUMENTS, Reproduction, _merge


def measure(out: str, game: str, seeds: int, population: str) -> dict[str, float]:
    """Build the adapt stage's configs for the curves adapting to `population` and time checking and packing them."""
    start = time.perf_counter()
    repro = Reproduction(plan_for(game, seeds=seeds), Path(out) / game)
    cfgs = []
    for target, name, settings, egos_of in repro.adapt_jobs():
        if Path(target).name != population:
            continue
        raw = _merge({"name": name, "population": target, "partners": repro.adapt_partners(target)}, settings)
        cfgs.append(config_files.checked({**raw, "runs": repro.egos(egos_of)}, AdaptConfig, ARGUMENTS).first)
    built = time.perf_counter()
    curves = 0
    for cfg in cfgs:  # what run_adaptations does before Tune: check every curve, then its packing key
        pairs = adaptation_curves(cfg)
        for pair in pairs:
            adapt_curve(cfg, pair["run"], pair["partner"])
        for pair in pairs:
            curve_packing_key(cfg, pair)
        curves += len(pairs)
    done = time.perf_counter()
    return {"configs": len(cfgs), "curves": curves, "build_s": built - start, "check_and_pack_s": done - built}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", help="a reproduce output folder whose train stage is done")
    parser.add_argument("--game", default="bandit")
    parser.add_argument("--seeds", type=int, default=10, help="the seeds the folder was run with")
    parser.add_argument("--population", required=True, help="time the curves adapting to this population")
    parser.add_argument("--baseline", help="a worktree of the code to compare with")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:  # one measurement in a fresh process (cold caches) of the code on its PYTHONPATH, printed as JSON
        print(json.dumps(measure(args.out, args.game, args.seeds, args.population)))
        return
    here = str(Path(__file__).resolve().parents[1])
    codes = {"this code": here, **({"baseline": str(Path(args.baseline).resolve())} if args.baseline else {})}
    rows: dict[str, list[dict[str, float]]] = {name: [] for name in codes}
    for name in alternating(list(codes), args.repeats):
        # The child runs this file by path, so its rllib_conv (and _common) come from the code measured.
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([codes[name], here]), "OMP_NUM_THREADS": "1"}
        cmd = [sys.executable, __file__, args.out, "--game", args.game, "--seeds", str(args.seeds)]
        done = subprocess.run([*cmd, "--population", args.population, "--child"], env=env, capture_output=True, text=True)
        if done.returncode:
            raise SystemExit(f"adapt_setup: the {name} run failed:\n{done.stderr[-2000:]}")
        rows[name].append(json.loads(done.stdout.strip().splitlines()[-1]))
    print(f"{'code':>10} {'curves':>7} {'check+pack s (median)':>22} {'ms per curve':>13}")
    summary = {}
    for name, runs in rows.items():
        seconds = sorted(r["check_and_pack_s"] for r in runs)[len(runs) // 2]
        summary[name] = {"runs": runs, "median_check_and_pack_s": seconds, "ms_per_curve": 1000 * seconds / runs[0]["curves"]}
        print(f"{name:>10} {runs[0]['curves']:>7} {seconds:>22.2f} {summary[name]['ms_per_curve']:>13.2f}")
    if "baseline" in summary:
        ratio = summary["baseline"]["median_check_and_pack_s"] / summary["this code"]["median_check_and_pack_s"]
        summary["speedup"] = ratio
        print(f"speed-up: {ratio:.1f}x")
    print("wrote", write_result("adapt_setup", {"folder": args.out, "population": args.population, **summary}))


if __name__ == "__main__":
    main()
