"""How much of a trained modular ego's policy its heads carry, where the rules decide and where conventions do.

For every trial of each trained-ego experiment, on the states the marginals are measured
on (`marginal_states`: every context of the bandit; the states P1 visits playing the
oracle with the training partners on blocks), split into *rule* states (one optimal
action) and *convention* states (more than one):
- heads: mean over heads and states of sum_a (h(a) - mean_b h(b))^2 for the heads' own
  outputs h, the quantity `head_l2` penalises (`head_size`);
- task: the same for the task module's logits.
Without the head penalty the heads push the rule moves about as hard as the task module;
with it they hold almost nothing there and keep what differs between partners.

    .venv/bin/python -m benchmarks.head_sizes ROOT/blocks/runs/blocks-perm__modular-lam0.5 \\
        ROOT/blocks/runs/blocks-perm__modular-lam0.5-hl0.01 --name head_sizes_blocks
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd
import torch

from benchmarks._common import write_result
from rllib_conv import partners
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.learners.head_penalty import head_size
from rllib_conv.modules.multi import ego_id
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import load_module
from rllib_conv.training.experiment import trial_config
from rllib_conv.training.marginal_distance import (
    marginal_states,
    optimal_actions,
)


@torch.no_grad()
def head_sizes(experiment: Path, episodes: int, seed: int) -> pd.DataFrame:
    """One row per trial: head and task sizes on rule and convention states."""
    rows, states = [], {}
    for trial in trial_folders(experiment):
        exp = trial_config(trial)
        pop = partners.get(exp.population)
        if pop.name not in states:  # the trials of an experiment usually share their population
            obs, mask = marginal_states(pop, episodes, seed)
            states[pop.name] = obs, mask, optimal_actions(pop.env, pop.env_config, obs, mask).sum(axis=1) == 1
        obs, mask, rule = states[pop.name]
        module = load_module(last_checkpoint(trial))
        # Unmasked: the games with an oracle have no illegal actions, and masked logits would swamp the sizes.
        z, task_logits = module.task.policy(torch.as_tensor(obs), None)
        outputs = torch.stack([module[ego_id(e.name)].pi(z) for e in pop.entries("train")])
        row = {"experiment": experiment.name, "trial": trial.name, "seed": exp.seed, "head_l2": exp.head_l2}
        for kind, where in (("rule", rule), ("convention", ~rule)):
            row[f"heads, {kind}"] = head_size(outputs[:, where]).item()
            row[f"task, {kind}"] = head_size(task_logits[None, where]).item()
        rows.append(row)
    return pd.DataFrame(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("experiments", type=Path, nargs="+", help="trained modular ego experiment (or trial) folders")
    parser.add_argument("--episodes", type=int, default=200, help="episodes per training partner for the blocks states")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--name", required=True, help="results/<name>.json")
    args = parser.parse_args()
    table = pd.concat([head_sizes(e, args.episodes, args.seed) for e in args.experiments], ignore_index=True)
    sizes = [c for c in table.columns if "," in c]
    means = table.groupby(["experiment", "head_l2"], sort=False)[sizes].mean()
    print(means.round(2).to_string())
    path = write_result(
        args.name,
        {
            "experiments": [str(e) for e in args.experiments],
            "episodes": args.episodes,
            "mean": means.reset_index().to_dict(orient="records"),
            "trials": table.to_dict(orient="records"),
        },
    )
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
