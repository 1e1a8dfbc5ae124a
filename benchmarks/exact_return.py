"""Scoring one adaptation point on blocks: the exact expected return against 200 sampled episodes.

An ego network of the paper's blocks size (80 hidden units, fresh weights) plays P1 with
each of the 6 permutation partners of `blocks-perm`; one way scores it by
`envs.game("blocks").exact_return` (a sum over 12 goals and every move), the other by 200
sampled episodes (the adaptation protocol's default), timed alternately in one process.
Prints the medians, their ratio and how far the sampled means fall from the exact values
(in their own standard errors); writes `benchmarks/results/exact_return.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.exact_return [--rounds 20] [--episodes 200]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from benchmarks._common import median_seconds, write_result
from rllib_conv import envs, partners
from rllib_conv.partners.episodes import play_episodes
from rllib_conv.partners.trained import PolicyPartner


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rounds", type=int, default=20, help="timings per way (default 20)")
    parser.add_argument("--episodes", type=int, default=200, help="sampled episodes per point (default 200)")
    args = parser.parse_args()
    torch.manual_seed(0)
    net = torch.nn.Sequential(
        torch.nn.Linear(35, 80), torch.nn.Tanh(), torch.nn.Linear(80, 80), torch.nn.Tanh(), torch.nn.Linear(80, 6)
    )
    ego = PolicyPartner("ego", lambda obs, mask: net(obs), greedy=False, seed=0, memo=True)
    exact_fn, env = envs.game("blocks").exact_return, envs.make("blocks")
    rows = []
    for entry in partners.get("blocks-perm").partners:
        players = {"player_0": ego, "player_1": entry.build()}
        seconds = median_seconds(
            {"exact": lambda: exact_fn(players, {}), "sampled": lambda: play_episodes(env, players, args.episodes, 0)},
            args.rounds,
        )
        scores = play_episodes(env, players, args.episodes, 0)
        exact = exact_fn(players, {})
        stderr = float(scores.std(ddof=1) / np.sqrt(len(scores)))
        rows.append(
            {
                "partner": entry.name,
                "exact_ms": 1000 * seconds["exact"],
                "sampled_ms": 1000 * seconds["sampled"],
                "speed-up": seconds["sampled"] / seconds["exact"],
                "exact_return": exact,
                "sampled_mean": float(scores.mean()),
                "sampled_off_by_stderrs": (float(scores.mean()) - exact) / stderr if stderr else float("nan"),
            }
        )
    print(f"{'partner':>12} {'exact ms':>9} {'sampled ms':>11} {'speed-up':>9} {'exact':>7} {'sampled':>8} {'off (se)':>9}")
    for r in rows:
        print(
            f"{r['partner']:>12} {r['exact_ms']:9.2f} {r['sampled_ms']:11.1f} {r['speed-up']:8.1f}x "
            f"{r['exact_return']:7.3f} {r['sampled_mean']:8.3f} {r['sampled_off_by_stderrs']:+9.2f}"
        )
    path = write_result("exact_return", {"rounds": args.rounds, "episodes": args.episodes, "rows": rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
