"""Overcooked-AI moves per second: the package's raw MDP beside our PettingZoo env (with its grid encoding).

Both play random actions on cramped_room, side by side in one run: the raw loop calls
`OvercookedGridworld.get_state_transition` and nothing else; ours calls `OvercookedEnv.step`,
which adds the rewards, the infos and both players' observations. A move is one player's
action (two per env step), as in `benchmarks/env_throughput.py`. Target: ours >= 50% of raw.
Prints a table and writes `benchmarks/results/overcooked_env.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.overcooked_env [--steps 20000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import subprocess
import time

import numpy as np
import pandas as pd

from benchmarks._common import write_result
from rllib_conv.envs.overcooked import ACTIONS, NUM_ACTIONS, OvercookedEnv


def raw_moves_per_second(layout: str, steps: int, seed: int, horizon: int = 400) -> float:
    """The package's MDP alone: `get_state_transition` with random joint actions, a new episode every `horizon` steps."""
    mdp = OvercookedEnv(layout, horizon=horizon).mdp
    rng = np.random.default_rng(seed)
    picks = rng.integers(NUM_ACTIONS, size=(steps, 2))
    state = mdp.get_standard_start_state()
    start = time.perf_counter()
    for a, b in picks:
        state, _ = mdp.get_state_transition(state, (ACTIONS[a], ACTIONS[b]))
        if state.timestep >= horizon:
            state = mdp.get_standard_start_state()
    return 2 * steps / (time.perf_counter() - start)


def env_moves_per_second(layout: str, steps: int, seed: int, horizon: int = 400) -> float:
    """Our env: `step` with random actions (rewards, infos and both observations), `reset` at the horizon."""
    env = OvercookedEnv(layout, horizon=horizon)
    rng = np.random.default_rng(seed)
    picks = rng.integers(NUM_ACTIONS, size=(steps, 2)).tolist()
    env.reset(seed=seed)
    start = time.perf_counter()
    for a, b in picks:
        env.step({"player_0": a, "player_1": b})
        if not env.agents:
            env.reset()
    return 2 * steps / (time.perf_counter() - start)


def cpu_model() -> str:
    """The CPU model as `lscpu` names it."""
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return next((line.split(":", 1)[1].strip() for line in out.splitlines() if line.startswith("Model name")), "unknown")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layout", default="cramped_room")
    parser.add_argument("--steps", type=int, default=20000, help="env steps per measurement (two moves each)")
    parser.add_argument("--repeats", type=int, default=3, help="best of this many measurements, raw and ours interleaved")
    args = parser.parse_args()
    raw, ours = [], []
    for r in range(args.repeats):
        raw.append(raw_moves_per_second(args.layout, args.steps, seed=r))
        ours.append(env_moves_per_second(args.layout, args.steps, seed=r))
    row = {
        "layout": args.layout,
        "raw_mdp_moves_per_s": max(raw),
        "env_moves_per_s": max(ours),
        "env/raw": max(ours) / max(raw),
        "raw_runs": raw,
        "env_runs": ours,
    }
    table = pd.DataFrame([{k: row[k] for k in ("layout", "raw_mdp_moves_per_s", "env_moves_per_s", "env/raw")}])
    print(table.to_string(index=False, float_format="{:.0f}".format, formatters={"env/raw": "{:.2f}".format}))
    cpu = cpu_model()
    print(f"CPU: {cpu}; target env/raw >= 0.50: {'met' if row['env/raw'] >= 0.5 else 'NOT met'}")
    path = write_result(
        "overcooked_env",
        {"steps": args.steps, "repeats": args.repeats, "lscpu_model": cpu, "target_env_over_raw": 0.5, "rows": [row]},
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
