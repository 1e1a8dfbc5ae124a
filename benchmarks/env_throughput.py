"""Random-legal-action steps per second of each game: the ceiling any training loop can reach.

Measures each built-in game twice, side by side in one run: the raw PettingZoo env, and
the same env through the RLlib adapter (`PettingZooMultiAgentEnv`) that training uses.
Prints a table and writes `benchmarks/results/env_throughput.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.env_throughput [--steps 20000]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pandas as pd
from pettingzoo.utils.env import AECEnv

from benchmarks._common import write_result
from rllib_conv import envs
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv

GAMES = {"bandit": {"symmetric": 2}, "blocks": {}, "hanabi": {}}


def _legal(rng: np.random.Generator, mask: np.ndarray) -> int:
    return int(rng.choice(np.flatnonzero(mask)))


def raw_steps_per_second(name: str, config: dict, steps: int, seed: int = 0) -> float:
    """Step the PettingZoo env with random legal actions; return agent moves per second."""
    env, rng, done = envs.make(name, **config), np.random.default_rng(seed), 0
    obs = env.reset(seed=seed)
    obs = obs[0] if isinstance(obs, tuple) else obs  # parallel envs return (obs, infos)
    start = time.perf_counter()
    while done < steps:
        if isinstance(env, AECEnv):
            obs, _, term, trunc, _ = env.last()
            if term or trunc:
                env.step(None)
                if not env.agents:
                    env.reset()
                continue
            env.step(_legal(rng, obs["action_mask"]))
            done += 1
        else:
            if not env.agents:
                obs, _ = env.reset()
            obs, *_ = env.step({a: _legal(rng, obs[a]["action_mask"]) for a in env.agents})
            done += len(env.possible_agents)
    return done / (time.perf_counter() - start)


def adapter_steps_per_second(name: str, config: dict, steps: int, seed: int = 0) -> float:
    """Step the RLlib adapter with random legal actions; return agent moves per second."""
    env, rng, done = PettingZooMultiAgentEnv(envs.make(name, **config)), np.random.default_rng(seed), 0
    obs, _ = env.reset(seed=seed)
    start = time.perf_counter()
    while done < steps:
        actions = {a: _legal(rng, o["action_mask"]) for a, o in obs.items()}
        obs, _, terms, truncs, _ = env.step(actions)
        done += len(actions)
        if terms["__all__"] or truncs["__all__"]:
            obs, _ = env.reset()
    return done / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000, help="agent moves per measurement")
    parser.add_argument("--repeats", type=int, default=3, help="best of this many measurements")
    args = parser.parse_args()
    rows = []
    for name, config in GAMES.items():
        raw = max(raw_steps_per_second(name, config, args.steps, seed=r) for r in range(args.repeats))
        adapted = max(adapter_steps_per_second(name, config, args.steps, seed=r) for r in range(args.repeats))
        rows.append(
            {"env": name, "config": config, "raw_moves_per_s": raw, "adapter_moves_per_s": adapted, "adapter/raw": adapted / raw}
        )
    table = pd.DataFrame(rows)
    print(table.to_string(index=False, float_format="{:.0f}".format, formatters={"adapter/raw": "{:.2f}".format}))
    path = write_result("env_throughput", {"steps": args.steps, "repeats": args.repeats, "rows": rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
