"""One learner update (all epochs and minibatches of one train batch) by an older commit and now, side by side.

    OMP_NUM_THREADS=1 python -m benchmarks.learner_update --old-commit COMMIT [--games bandit blocks hanabi] [--replicas 3] [--repeats 7] [--rounds 2] [--name NAME]
    OMP_NUM_THREADS=1 python -m benchmarks.learner_update --precision bfloat16 [--games ...] [--name NAME]

Isolates the learner from sampling and Tune: for each case (a population and a method, 3
seeds packed as `train` packs them) one train batch is sampled after one warm-up iteration,
then the learner updates on that same batch `--repeats` times; the median is the case's
time. Each code (a git worktree of `--old-commit`, this checkout) measures every case in a
fresh process, the two alternating for `--rounds` rounds (A B, B A) so the shared machine's
drift falls on both alike; the table gives the median over rounds and the ratio. Cases with
regulariser weight 0 (`modular` lam 0, `no_task_logits`) show what computing only each row's
own head saves; the user study's 24 heads show it at its largest. With `--precision bfloat16`
instead of `--old-commit`, this checkout's float32 learner is "before" and its opt-in bfloat16
learner (`ppo.precision`) "now", alternating the same way. Written to
`benchmarks/results/<NAME>.json` (default `learner_update`).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import pandas as pd
import ray

from benchmarks._common import alternating, run_with_code, write_result
from benchmarks.reproduce_walltime import REPO, worktree
from benchmarks.train_throughput import fixed_update, population_of
from rllib_conv.training.algorithm import Replica, build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.experiment import ExperimentConfig

# (game, population or None for the game's `population_of`, method, lam): the plans' trained egos that differ in cost.
CASES = {
    "bandit": [
        ("bandit-s2-hand", "modular", 0.5),
        ("bandit-s2-hand", "modular", 0.0),
        ("bandit-s2-hand", "no_task_logits", 0.0),
        ("bandit-s2-hand", "agg", 0.0),
        ("bandit-user-study", "modular", 0.5),
        ("bandit-user-study", "no_task_logits", 0.0),
    ],
    "blocks": [(None, "modular", 0.5), (None, "no_task_logits", 0.0)],
    "hanabi": [(None, "modular", 0.5), (None, "no_task_logits", 0.0)],
}


def case_name(game: str, population: str | None, method: str, lam: float) -> str:
    """A case's row label, e.g. `bandit-user-study modular lam0.5`."""
    return f"{population or game} {method}" + (f" lam{lam:g}" if method == "modular" else "")


def measure(games: list[str], replicas: int, repeats: int, precision: str) -> dict[str, float]:
    """Median milliseconds of one learner update per case, with the rllib_conv this process imports."""
    ppo = {} if precision == "float32" else {"ppo": {"precision": precision}}  # an older commit may lack the key
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for game in games:
            for population, method, lam in CASES[game]:
                pop = population or population_of(game, Path(tmp))
                exps = [ExperimentConfig(population=pop, method=method, lam=lam, seed=s, **ppo) for s in range(replicas)]
                algo = build_ppo_config([Replica(resolve(e)) for e in exps]).build_algo()
                try:
                    algo.train()  # warm-up: optimizer states exist, lazy set-up done
                    update = fixed_update(algo, algo.env_runner.sample())
                    times = []
                    for _ in range(repeats):
                        start = time.perf_counter()
                        update()
                        times.append(time.perf_counter() - start)
                    out[case_name(game, population, method, lam)] = 1e3 * statistics.median(times)
                finally:
                    algo.stop()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old-commit", help="the commit to compare against (required unless --precision or --child)")
    parser.add_argument(
        "--precision", choices=["float32", "bfloat16"], default="float32", help="the learner's precision (`ppo.precision`)"
    )
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks"], choices=list(CASES))
    parser.add_argument("--replicas", type=int, default=3, help="seeds packed per case")
    parser.add_argument("--repeats", type=int, default=7, help="timed updates per case and round")
    parser.add_argument("--rounds", type=int, default=2, help="measurements of each code")
    parser.add_argument("--name", default="learner_update")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print("MS " + json.dumps(measure(args.games, args.replicas, args.repeats, args.precision)))
        return
    if bool(args.old_commit) == (args.precision != "float32"):
        parser.error("give either --old-commit (a commit to compare this checkout against) or --precision bfloat16")
    child = ["--child", "--games", *args.games, "--replicas", str(args.replicas), "--repeats", str(args.repeats)]
    if args.old_commit:
        codes = {"before": (worktree(args.old_commit, Path(tempfile.mkdtemp(prefix="learner-update-"))), "float32")}
    else:
        codes = {"before": (REPO, "float32")}
    codes["now"] = (REPO, args.precision)
    runs: dict[str, list[dict[str, float]]] = {name: [] for name in codes}
    for name in alternating(list(codes), args.rounds):
        code, precision = codes[name]
        runs[name].append(json.loads(run_with_code(code, "learner_update", [*child, "--precision", precision], "MS")))
    rows = []
    for case in runs["now"][0]:
        before = statistics.median(r[case] for r in runs["before"])
        now = statistics.median(r[case] for r in runs["now"])
        rows.append({"case": case, "before_ms": before, "now_ms": now, "before/now": before / now})
    print(pd.DataFrame(rows).to_string(index=False, float_format="{:.2f}".format), flush=True)
    if args.old_commit:
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "remove", "--force", str(codes["before"][0])], check=False, capture_output=True
        )
    result = {"old_commit": args.old_commit, "precision": {name: p for name, (_, p) in codes.items()}}
    result.update(replicas=args.replicas, repeats=args.repeats, rounds=args.rounds)
    print(f"wrote {write_result(args.name, {**result, 'rows': rows, 'runs': runs})}")


if __name__ == "__main__":
    main()
