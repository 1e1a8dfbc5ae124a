"""Where the wall time of a small sweep goes: Ray start, trial start, training; embedded Ray vs a 2-node cluster.

A 4-trial sweep (bandit, 2 symmetric contexts, lam in {0, 0.5} x seed in {0, 1},
`--timesteps` env steps each) runs through `rllib-conv sweep` twice, side by side:
- `embedded`: a local Ray started by the sweep itself (2 CPUs);
- `2-node`: a `ray.cluster_utils.Cluster` on loopback, head 1 CPU + second node 1 CPU
  (same 2 cores in total), the sweep connecting with `--address`.
Per setting: Ray (cluster) start, sweep wall time, mean trial set-up (`setup_s` in each
trial's eval.json: building the algorithm, env runners, modules), mean trial training
(`wall_s`: training and final evaluation), and the rest (Tune scheduling, actor start-up,
result syncing) = sweep wall - trials' set-up and training / 2 trials in parallel.
Writes `benchmarks/results/sweep_overhead.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.sweep_overhead [--timesteps 2048]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import yaml

from benchmarks._common import write_result

PARALLEL = 2


def _sweep_config(folder: Path, timesteps: int) -> Path:
    sweep = {
        "name": "overhead",
        "population": "bandit-s2-hand",
        "lam": {"grid_search": [0.0, 0.5]},
        "seed": {"grid_search": [0, 1]},
        "run": {"timesteps": timesteps},
    }
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump(sweep))
    return path


def _run_sweep(config: Path, storage: Path, address: str | None) -> float:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "RAY_ADDRESS": ""}
    cmd = [sys.executable, "-m", "rllib_conv.cli", "sweep", str(config), "--storage", str(storage)]
    if address:
        cmd += ["--address", address]
    start = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"sweep failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
    return time.perf_counter() - start


def _trial_times(storage: Path) -> tuple[float, float]:
    evals = [json.loads(p.read_text()) for p in storage.glob("overhead/*/seed=*/eval.json")]
    if len(evals) != 4:
        raise RuntimeError(f"expected 4 finished trials under {storage}, found {len(evals)}")
    return sum(e["setup_s"] for e in evals) / 4, sum(e["wall_s"] for e in evals) / 4


def _row(setting: str, ray_start: float, wall: float, storage: Path) -> dict:
    setup, train = _trial_times(storage)
    return {
        "setting": setting,
        "ray_start_s": ray_start,
        "sweep_wall_s": wall,
        "trial_setup_s": setup,
        "trial_train_s": train,
        "other_s": wall - 4 * (setup + train) / PARALLEL,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=2048, help="env steps per trial (default 2048)")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="sweep_overhead_"))
    config = _sweep_config(work, args.timesteps)
    rows = []

    # Embedded: the sweep's own process starts Ray; time it apart with a bare start/stop.
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-c", "import ray; ray.init(num_cpus=2, include_dashboard=False); ray.shutdown()"],
        check=True,
        capture_output=True,
    )
    ray_start = time.perf_counter() - start
    rows.append(_row("embedded", ray_start, _run_sweep(config, work / "embedded", None), work / "embedded"))

    from ray.cluster_utils import Cluster

    os.environ["RAY_TMPDIR"] = tempfile.mkdtemp(prefix="rt", dir="/tmp")  # a private socket dir
    start = time.perf_counter()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    try:
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        ray_start = time.perf_counter() - start
        rows.append(_row("2-node", ray_start, _run_sweep(config, work / "cluster", cluster.address), work / "cluster"))
    finally:
        cluster.shutdown()

    table = pd.DataFrame(rows)
    ratio = {k: rows[1][k] / rows[0][k] for k in ("ray_start_s", "sweep_wall_s", "trial_setup_s", "trial_train_s")}
    with pd.option_context("display.float_format", "{:.1f}".format, "display.width", 200):
        print(table.to_string(index=False))
    print("2-node / embedded: " + ", ".join(f"{k} {v:.2f}x" for k, v in ratio.items()))
    path = write_result(
        "sweep_overhead", {"timesteps_per_trial": args.timesteps, "trials": 4, "rows": rows, "ratio_2node_over_embedded": ratio}
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
