"""Level-Based Foraging env steps per second: the package's raw `ForagingEnv` beside our PettingZoo env, 2-4 players.

Both play uniformly random legal actions on the default field (8x8, 3 food, full sight, 50 steps),
side by side in one run: the raw loop calls `ForagingEnv.step` with the package's own valid
actions; ours calls `LBFEnv.step`, which adds the action check, the shared reward and the
observation dicts with their masks. An env step is one joint step of every player. Prints a
table and writes `benchmarks/results/lbf_env.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.lbf_env [--steps 10000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd

from benchmarks._common import write_result
from benchmarks.overcooked_env import cpu_model
from rllib_conv import envs


def raw_steps_per_second(players: int, steps: int, seed: int) -> float:
    """The package's env alone (as ours builds it): random valid actions, a new episode when it is over."""
    forage = envs.make("lbf", players=players).forage
    draws = np.random.default_rng(seed).random((steps, players))
    forage.reset(seed=seed)
    start = time.perf_counter()
    for row in draws:
        valid = [forage._valid_actions[p] for p in forage.players]
        _, _, done, _, _ = forage.step([v[int(u * len(v))].value for v, u in zip(valid, row)])
        if done:
            forage.reset()
    return steps / (time.perf_counter() - start)


def env_steps_per_second(players: int, steps: int, seed: int) -> float:
    """Our env: random legal actions from each seat's mask, `reset` when the episode ends."""
    env = envs.make("lbf", players=players)
    draws = np.random.default_rng(seed).random((steps, players))
    obs, _ = env.reset(seed=seed)
    start = time.perf_counter()
    for row in draws:
        legal = [np.flatnonzero(obs[a]["action_mask"]) for a in env.possible_agents]
        obs, *_ = env.step({a: int(v[int(u * len(v))]) for a, v, u in zip(env.possible_agents, legal, row)})
        if not env.agents:
            obs, _ = env.reset()
    return steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=10000, help="env steps per measurement")
    parser.add_argument("--repeats", type=int, default=3, help="best of this many measurements, raw and ours interleaved")
    args = parser.parse_args()
    rows = []
    for players in (2, 3, 4):
        raw, ours = [], []
        for r in range(args.repeats):
            raw.append(raw_steps_per_second(players, args.steps, seed=r))
            ours.append(env_steps_per_second(players, args.steps, seed=r))
        rows.append(
            {
                "players": players,
                "raw_steps_per_s": max(raw),
                "env_steps_per_s": max(ours),
                "env/raw": max(ours) / max(raw),
                "raw_runs": raw,
                "env_runs": ours,
            }
        )
    table = pd.DataFrame([{k: row[k] for k in ("players", "raw_steps_per_s", "env_steps_per_s", "env/raw")} for row in rows])
    print(table.to_string(index=False, float_format="{:.0f}".format, formatters={"env/raw": "{:.2f}".format}))
    cpu = cpu_model()
    print(f"CPU: {cpu}")
    path = write_result("lbf_env", {"steps": args.steps, "repeats": args.repeats, "lscpu_model": cpu, "rows": rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
