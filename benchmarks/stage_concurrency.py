"""How one `reproduce` stage spreads its trials: embedded Ray versus a 2-node cluster on loopback, side by side.

A train stage of `--experiments` small bandit experiments (one seed each, `--timesteps`
env steps, 1 CPU a trial) runs through `train_stage` twice:
- `embedded`: the local Ray the stage starts itself (this machine's CPUs);
- `2-node`: a `ray.cluster_utils.Cluster` on loopback, head and second node with
  `--node-cpus` CPUs each, the stage connecting with `address`.
Per setting: CPUs Ray offers, trials, the most trials running at once (from each trial's
first and last result times), the nodes trials ran on (`node_id` in their results) and the
stage's wall time. On one machine the 2-node cluster shares the same cores, so its wall
time shows concurrency, not a speed-up; on real nodes the trials would spread the same way.
Writes `benchmarks/results/stage_concurrency.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.stage_concurrency [--experiments 8] [--timesteps 1024] [--node-cpus 2]
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
from typing import Any

import pandas as pd

from benchmarks._common import write_result

STAGE = """
import json, sys, time
import ray
from rllib_conv.pipelines.train import train_stage
from rllib_conv.training.experiment import checked
storage, address, n, steps = sys.argv[1], sys.argv[2] or None, int(sys.argv[3]), int(sys.argv[4])
raws = [{"name": f"bandit-s2-hand__lam{i}", "population": "bandit-s2-hand", "lam": 0.05 * i, "run": {"timesteps": steps}} for i in range(n)]
start = time.perf_counter()
train_stage([checked(raw) for raw in raws], storage, address, label="stage")
wall = time.perf_counter() - start
cpus = ray.cluster_resources().get("CPU")
print("STAGE " + json.dumps({"wall_s": wall, "cpus": cpus}))
"""


def _run(storage: Path, address: str, experiments: int, timesteps: int) -> dict[str, Any]:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "RAY_ADDRESS": ""}
    proc = subprocess.run(
        [sys.executable, "-c", STAGE, str(storage), address, str(experiments), str(timesteps)],
        env=env,
        capture_output=True,
        text=True,
    )
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("STAGE ")), None)
    if proc.returncode != 0 or line is None:
        raise RuntimeError((proc.stdout + proc.stderr)[-4000:])
    return json.loads(line[len("STAGE ") :])


def _spread(storage: Path) -> dict[str, Any]:
    """Peak concurrent trials and nodes used, from every trial's result.json of the stage's Tune run."""
    spans, nodes = [], set()
    for result in storage.glob("train-stage-*/*/result.json"):
        rows = [json.loads(ln) for ln in result.read_text().splitlines() if ln.strip()]
        if rows:
            # A trial runs from its first result minus that iteration's time to its last result.
            spans.append((rows[0]["timestamp"] - rows[0]["time_this_iter_s"], rows[-1]["timestamp"]))
            nodes |= {r["node_id"] for r in rows if "node_id" in r}
    events = sorted([(s, 1) for s, _ in spans] + [(e, -1) for _, e in spans])
    running = peak = 0
    for _, change in events:
        running += change
        peak = max(peak, running)
    return {"trials": len(spans), "peak_concurrent": peak, "nodes": len(nodes)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--experiments", type=int, default=8)
    parser.add_argument("--timesteps", type=int, default=1024)
    parser.add_argument("--node-cpus", type=int, default=2)
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="concurrency-"))
    rows = []
    embedded = _run(work / "embedded", "", args.experiments, args.timesteps)
    rows.append({"setting": "embedded", **embedded, **_spread(work / "embedded")})
    from ray.cluster_utils import Cluster

    start = time.perf_counter()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": args.node_cpus, "include_dashboard": False})
    try:
        cluster.add_node(num_cpus=args.node_cpus)
        cluster.wait_for_nodes()
        ray_start = time.perf_counter() - start
        two = _run(work / "two-node", cluster.address, args.experiments, args.timesteps)
    finally:
        cluster.shutdown()
    rows.append({"setting": "2-node", "ray_start_s": ray_start, **two, **_spread(work / "two-node")})
    print(pd.DataFrame(rows).to_string(index=False, float_format="{:.1f}".format))
    path = write_result(
        "stage_concurrency",
        {"experiments": args.experiments, "timesteps": args.timesteps, "node_cpus": args.node_cpus, "rows": rows},
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
