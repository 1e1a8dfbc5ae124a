"""What a trained modular ego brings to held-out partners before it adapts, piece by piece.

For every trial of a trained-ego experiment, the mean return with each test partner of
its population, sampled like the adaptation curves' evaluation (stochastic ego, `episodes`
episodes per pair), of:
- the task module alone: what a fresh partner head plays (adaptation step 0);
- each training partner's head: one learned convention, kept whole;
- the best training head for each test partner (an upper bound on picking one convention).
Where the task module alone scores below the heads, mixing the conventions move by move
costs more than committing to any one of them.

    .venv/bin/python -m benchmarks.head_crossplay ROOT/blocks/runs/blocks-selfplay__modular-lam0.5 \\
        --population ROOT/blocks/populations/blocks-selfplay --name head_crossplay_blocks_selfplay
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from benchmarks._common import write_result
from rllib_conv import envs, partners
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.modules.multi import ego_id
from rllib_conv.partners.episodes import play_episodes
from rllib_conv.partners.trained import PolicyPartner
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import ego_head_partner, load_module

TASK_ONLY = "task module alone"
BEST = "best training head"


def head_crossplay(experiment: Path, population: str, episodes: int, seed: int) -> pd.DataFrame:
    """Rows (trial, player, test partner, mean return); `player` is TASK_ONLY or a training partner's name."""
    pop = partners.get(population)
    env = envs.make(pop.env, **pop.env_config)
    ego_agent = next(a for a in env.possible_agents if a != pop.partner_agent)
    rows = []
    for trial in trial_folders(experiment):
        module = load_module(last_checkpoint(trial))
        players = {TASK_ONLY: PolicyPartner(TASK_ONLY, lambda o, m: module.task.policy(o, m).logits, seed=seed)}
        players |= {e.name: ego_head_partner(module, ego_id(e.name), seed) for e in pop.entries("train")}
        for name, player in players.items():
            for partner in pop.entries("test"):
                score = play_episodes(env, {ego_agent: player, pop.partner_agent: partner.build()}, episodes, seed)
                rows.append({"trial": trial.name, "player": name, "partner": partner.name, "mean_return": float(score.mean())})
    return pd.DataFrame(rows)


def summary(table: pd.DataFrame) -> pd.DataFrame:
    """Mean over test partners per trial for the task module, the heads on average, and the best head per partner."""
    heads = table[table["player"] != TASK_ONLY]
    per_trial = pd.DataFrame(
        {
            TASK_ONLY: table[table["player"] == TASK_ONLY].groupby("trial")["mean_return"].mean(),
            "training heads, mean": heads.groupby("trial")["mean_return"].mean(),
            BEST: heads.groupby(["trial", "partner"])["mean_return"].max().groupby("trial").mean(),
        }
    )
    return per_trial


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("experiment", type=Path, help="a trained modular ego experiment (or trial) folder")
    parser.add_argument("--population", required=True, help="the population its test partners come from (name or folder)")
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--name", required=True, help="results/<name>.json")
    args = parser.parse_args()
    table = head_crossplay(args.experiment, args.population, args.episodes, args.seed)
    per_trial = summary(table)
    print(per_trial.round(2).to_string())
    means = per_trial.mean()
    print("mean over trials: " + ", ".join(f"{k} {v:.2f}" for k, v in means.items()))
    path = write_result(
        args.name,
        {
            "experiment": str(args.experiment),
            "population": args.population,
            "episodes": args.episodes,
            "per_trial": per_trial.reset_index().to_dict(orient="records"),
            "mean": {k: float(v) for k, v in means.items()},
            "pairs": table.to_dict(orient="records"),
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
