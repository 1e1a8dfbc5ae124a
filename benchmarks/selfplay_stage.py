"""A whole self-play population by an older commit's code and by today's, side by side; and whether each is reproducible.

`rllib-conv partners train tune_configs/selfplay_<game>.yaml` from an empty folder, run by the
code of `--old-commit` (a git worktree) and by this checkout, `--rounds` times each in the
order old, new, new, old, ... (drift in the machine's speed falls on both alike). Prints the
wall times and the ratio of medians, and how many pairs' kept seats have the same weights in
every run of the same code; writes `benchmarks/results/selfplay_stage_<game>.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.selfplay_stage [--game bandit] [--old-commit 66f3779] [--rounds 2] [--work DIR]
"""

from __future__ import annotations

import argparse
import os
import pickle
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks._common import alternating, write_result
from benchmarks.reproduce_walltime import REPO, worktree

OLD_COMMIT = "66f3779"  # before self-play sampled through BatchedEnvRunner and Tune reused workers


def train(code: Path, game: str, out: Path) -> float:
    """Train the shipped self-play population of `game` with the rllib_conv of `code` into `out`; wall seconds."""
    env = {**os.environ, "PYTHONPATH": str(code), "OMP_NUM_THREADS": "1", "RAY_ADDRESS": ""}
    cmd = [
        sys.executable,
        "-m",
        "rllib_conv.cli",
        "partners",
        "train",
        f"tune_configs/selfplay_{game}.yaml",
        "--out",
        str(out / "pops"),
        "--storage",
        str(out / "runs"),
    ]
    start = time.perf_counter()
    proc = subprocess.run(cmd, cwd=code, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} with {code} failed:\n{(proc.stdout + proc.stderr)[-4000:]}")
    return time.perf_counter() - start


def seat_weights(out: Path) -> dict[str, dict[str, np.ndarray]]:
    """Each kept seat's module weights, by partner name."""
    (population,) = (out / "pops").iterdir()
    return {p.name: pickle.loads((p / "module_state.pkl").read_bytes()) for p in sorted((population / "partners").iterdir())}


def same_pairs(runs: list[Path]) -> int:
    """How many pairs' kept seats have exactly the same weights in every one of `runs`."""
    weights = [seat_weights(r) for r in runs]
    return sum(
        all(
            name in w and all(np.array_equal(np.asarray(w[name][k]), np.asarray(v)) for k, v in weights[0][name].items())
            for w in weights[1:]
        )
        for name in weights[0]
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--game", default="bandit", choices=["bandit", "blocks", "hanabi"])
    p.add_argument("--old-commit", default=OLD_COMMIT)
    p.add_argument("--rounds", type=int, default=2, help="populations per code")
    p.add_argument("--work", type=Path, default=None, help="where the old worktree and the populations go (default: a temp dir)")
    args = p.parse_args()
    work = args.work or Path(tempfile.mkdtemp(prefix="selfplay-stage-"))
    codes = {"old": worktree(args.old_commit, work), "new": REPO}
    rows, folders = [], {"old": [], "new": []}
    for i, which in enumerate(alternating(("old", "new"), args.rounds)):
        out = work / f"{which}-{i // 2}"
        rows.append({"code": which, "wall_s": train(codes[which], args.game, out)})
        folders[which].append(out)
        print(pd.DataFrame(rows).to_string(index=False, float_format="{:.1f}".format), flush=True)
    pairs = len(seat_weights(folders["new"][0]))
    walls = {w: statistics.median(r["wall_s"] for r in rows if r["code"] == w) for w in codes}
    summary = {
        "old_s": walls["old"],
        "new_s": walls["new"],
        "old/new": walls["old"] / walls["new"],
        "pairs": pairs,
        "same_weights_every_run": {w: same_pairs(f) for w, f in folders.items()},
    }
    print(summary)
    print(
        f"wrote {write_result(f'selfplay_stage_{args.game}', {'old_commit': args.old_commit, 'rounds': args.rounds, 'rows': rows, 'summary': summary})}"
    )


if __name__ == "__main__":
    main()
