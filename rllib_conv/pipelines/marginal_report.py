"""`rllib-conv marginals`: how close each trained task module is to the true marginals (the paper's marginals figure).

One row per trained ego whose method has a learned estimate of the marginals (the
registry's `marginals`): the L1 distance of `rllib_conv.training.marginal_distance` on the
states its population's game defines.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from rllib_conv import partners
from rllib_conv.common.atomic_files import replaced_atomically
from rllib_conv.common.methods import method
from rllib_conv.common.run_folders import MARGINALS_FILE_COLUMNS
from rllib_conv.modules.multi import AGG_HEAD_ID
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import load_module
from rllib_conv.training.experiment import trial_config
from rllib_conv.training.marginal_distance import marginal_distances, marginal_states


def marginal_report(trials: list[Path], episodes: int = 200, seed: int = 0) -> pd.DataFrame:
    """One row per trained ego with a task output: its task module's distance to the true marginals."""
    rows, states = [], {}
    for trial in trials:
        exp = trial_config(trial)
        marginals = method(exp.method).marginals
        if marginals is None:
            continue
        pop = partners.get(exp.population)
        key = (pop.name, episodes, seed)
        if key not in states:
            states[key] = marginal_states(pop, episodes, seed)
        obs, mask = states[key]
        module = load_module(last_checkpoint(trial))
        d = marginal_distances(module, pop.env, pop.env_config, obs, mask, AGG_HEAD_ID if marginals == "network" else None)
        rows.append(
            {
                "run": str(trial),
                "env": pop.env,
                "env_config": str(pop.env_config),
                "population": pop.name,
                "method": exp.method,
                "lam": exp.lam,
                "z_dim": exp.model.z_dim or exp.model.hidden,
                "seed": exp.seed,
                "distance": d["paper"],
                "distance_all_states": d["all"],
                "states": len(obs),
            }
        )
    return pd.DataFrame(rows, columns=list(MARGINALS_FILE_COLUMNS))


def write_marginal_report(trials: list[Path], path: str | Path, episodes: int = 200, seed: int = 0) -> pd.DataFrame:
    """The `marginal_report` of `trials`, written to the CSV `path`; ValueError (nothing written) when no ego has an estimate."""
    table = marginal_report(trials, episodes=episodes, seed=seed)
    if table.empty:
        raise ValueError(
            f"RUNS: none of the {len(trials)} trained egos has a learned estimate of the marginals (the method registry's `marginals`)"
        )
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(path) as tmp:
        table.to_csv(tmp, index=False)
    return table
