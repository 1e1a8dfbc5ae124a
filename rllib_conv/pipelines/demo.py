"""The README's demo: train the modular ego on the bandit, then show what it learned.

Trains `tune_configs/bandit_modular.yaml` (lam 0.5, 2 symmetric contexts, 4 hand-designed
partners, the paper's 10 000 steps) through Tune on a local Ray, then prints each
partner's convention with the ego's expected return, and the task module's action
distribution per context beside the true marginals.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from rllib_conv import partners
from rllib_conv.common.config_files import Checked
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.envs.bandit import CollaborativeBanditEnv, oracle_marginals
from rllib_conv.envs.bandit.oracle import bandit_states
from rllib_conv.pipelines.train import run
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import load_module, task_probs
from rllib_conv.training.experiment import ExperimentConfig

DEMO_CONFIG = "bandit_modular.yaml"  # a shipped config (`tune_configs/` in the repository)


def _arms(p: np.ndarray, top: int = 3) -> str:
    order = np.argsort(-p)[:top]
    return "  ".join(f"{a}:{p[a]:.2f}" for a in order if p[a] >= 0.005)


def demo(config: Checked[ExperimentConfig], storage: str | Path = "runs", address: str | None = None) -> None:
    """Train the demo's experiment `config`, then print per-partner returns and the task module's marginals.

    `config` is `DEMO_CONFIG` with `--set name=demo` and the user's overrides, checked
    (`experiment.load`; the CLI checks it before Ray loads).
    """
    result = run(config, storage=storage, address=address)[0]
    if result.error is not None:
        raise RuntimeError(f"demo training failed: {result.error}")
    exp = config.first
    pop = partners.get(exp.population)
    m = result.metrics
    rows = [
        {
            "partner": e.name,
            "convention (arm per context)": e.params["arms"],
            "expected return": m[f"eval/exact/{e.name}"],
            "200 episodes": f"{m[f'eval/mean/{e.name}']:.3f} ± {m[f'eval/stderr/{e.name}']:.3f}",
        }
        for e in pop.entries("train")
    ]
    print(f"\nModular ego (lam {exp.lam}) after {m['env_steps']} env steps ({m['wall_s']:.0f} s), run folder {result.path}")
    print(pd.DataFrame(rows).to_string(index=False, float_format="{:.3f}".format))
    env = CollaborativeBanditEnv(**pop.env_config)
    obs, mask = bandit_states(pop.env_config)
    ego = trial_folders(result.path)[
        0
    ]  # the trained ego the trial exported (its one seed); the trial's own checkpoint is the packed algorithm's
    probs = task_probs(load_module(last_checkpoint(ego)), obs, mask)
    truth = oracle_marginals(env.prizes)
    table = pd.DataFrame(
        {
            "context": range(env.num_contexts),
            "task module p(arm)": [_arms(p) for p in probs],
            "true marginals": [_arms(t) for t in truth],
            "L1": np.abs(probs - truth).sum(axis=1),
        }
    )
    print("\nTask module vs the true marginals (uniform over each context's good arms):")
    print(table.to_string(index=False, float_format="{:.3f}".format))
    print(
        f"L1 distance: {m['eval/marginal_distance/paper']:.3f} on the symmetric contexts (paper: 0.01-0.02), "
        f"{m['eval/marginal_distance/all']:.3f} over all contexts"
    )
