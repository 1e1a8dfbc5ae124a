"""Ego-training env steps/s per trial (3 packed seeds, `train_throughput.py`'s `ours_3`) by an older commit and now, side by side.

    OMP_NUM_THREADS=1 python -m benchmarks.throughput_against --old-commit COMMIT [--games blocks hanabi] [--methods modular agg] [--seconds 20] [--rounds 3] [--population P] [--name NAME]

Each measurement is a fresh process with the rllib_conv of either a git worktree of
`--old-commit` or this checkout, the two alternating (A B, B A, ...) so that the shared
machine's drift falls on both alike; the table gives each one's median and the ratio.
`--methods` trains other egos than the paper's (`modular`, lam 0.5), e.g. BaselineAgg, whose
one head takes 4x the minibatch steps; `--population` another partner population than
`train_throughput`'s (e.g. a self-play population's folder: 4 heads, not 1). Written to `benchmarks/results/<NAME>.json` (default `throughput_against`).
"""

from __future__ import annotations

import argparse
import itertools
import statistics
import subprocess
import tempfile
from pathlib import Path

import pandas as pd
import ray

from benchmarks._common import alternating, run_with_code, write_result
from benchmarks.reproduce_walltime import REPO, worktree
from benchmarks.train_throughput import ours, population_of, steps_per_second

GAMES = ("bandit", "blocks", "hanabi")
METHODS = ("modular", "agg", "no_task_logits", "maml")


def measure(game: str, method: str, seconds: float, population: str | None = None) -> float:
    """`ours_3` env steps/s on `game` (an ego of `method`, against `population` or the game's default one) with the rllib_conv this process imports."""
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    with tempfile.TemporaryDirectory() as tmp:
        return steps_per_second(ours(population or population_of(game, Path(tmp)), 3, method=method), seconds, replicas=3)[0]


def run_child(code: Path, game: str, method: str, seconds: float, population: str | None) -> float:
    """`measure` in a fresh process whose rllib_conv is `code`'s (and whose benchmark scripts are this checkout's)."""
    args = [
        "--child",
        game,
        "--methods",
        method,
        "--seconds",
        str(seconds),
        *(["--population", population] if population else []),
    ]
    return float(run_with_code(code, "throughput_against", args, "STEPS"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old-commit", help="the commit to compare against (required unless --child)")
    parser.add_argument("--games", nargs="+", default=["blocks", "hanabi"], choices=GAMES)
    parser.add_argument(
        "--methods", nargs="+", default=["modular"], choices=METHODS, help="the egos trained (each on every game)"
    )
    parser.add_argument("--seconds", type=float, default=20.0, help="minimum timed training per measurement")
    parser.add_argument("--rounds", type=int, default=3, help="measurements of each code per game")
    parser.add_argument(
        "--population", help="the partners' population (name or manifest folder; one game): default train_throughput's per game"
    )
    parser.add_argument("--name", default="throughput_against")
    parser.add_argument("--child", choices=GAMES, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(f"STEPS {measure(args.child, args.methods[0], args.seconds, args.population)}")
        return
    if not args.old_commit:
        parser.error("--old-commit is required: the commit to compare this checkout against")
    if args.population and len(args.games) != 1:
        parser.error(f"--population {args.population} is one game's: give one --games, not {len(args.games)}")
    work = Path(tempfile.mkdtemp(prefix="throughput-against-"))
    codes = {"before": worktree(args.old_commit, work), "now": REPO}
    rows = []
    for game, method in itertools.product(args.games, args.methods):
        runs: dict[str, list[float]] = {name: [] for name in codes}
        for name in alternating(list(codes), args.rounds):
            runs[name].append(run_child(codes[name], game, method, args.seconds, args.population))
        before, now = statistics.median(runs["before"]), statistics.median(runs["now"])
        rows.append({"env": game, "method": method, "before": before, "now": now, "now/before": now / before, "runs": runs})
        print(pd.DataFrame(rows).drop(columns="runs").to_string(index=False, float_format="{:.2f}".format), flush=True)
    subprocess.run(
        ["git", "-C", str(REPO), "worktree", "remove", "--force", str(codes["before"])], check=False, capture_output=True
    )
    meta = {"old_commit": args.old_commit, "seconds": args.seconds, "rounds": args.rounds, "population": args.population}
    path = write_result(args.name, {**meta, "rows": rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
