"""Train the modular ego through Ray Tune: one experiment config (grids allowed) -> one Tune run.

Each trial is an `EgoTrainable` wrapping an RLlib PPO algorithm built from the trial's
`ExperimentConfig`. The trial folder holds Tune's `params.json`/`progress.csv`
(per-iteration metrics, per-partner returns included), our resolved `config.yaml`,
checkpoints, and `eval.json` (final per-partner returns and marginal distances).
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from ray import tune

from rllib_conv.common.methods import method
from rllib_conv.common.run_folders import CONFIG_FILE, EVAL_FILE
from rllib_conv.envs.oracles import has_oracle
from rllib_conv.learners.marginal_learner import HEAD_L2_KEY, MARGINAL_REG_KEY
from rllib_conv.modules.multi import AGG_HEAD_ID, partner_id
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.ego_setup import EgoSetup, resolve
from rllib_conv.training.evaluate import ego_return
from rllib_conv.training.experiment import ExperimentConfig, validate
from rllib_conv.training.maml import MetaTrainer
from rllib_conv.training.marginals import marginal_distances, marginal_states
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.tuning import fit, to_param_space


def summarize(result: dict[str, Any], setup: EgoSetup) -> dict[str, Any]:
    """Reduce RLlib's result dict to the metrics we report: steps, per-partner returns, regulariser."""
    runners = result.get("env_runners", {})
    module_returns = runners.get("module_episode_returns_mean", {})
    per_partner = {
        f"return/{e.name}": float(module_returns[partner_id(e.name)]) for e in setup.train if partner_id(e.name) in module_returns
    }
    learners = result.get("learners", {})
    return {
        "env_steps": int(runners.get("num_env_steps_sampled_lifetime", 0)),
        "return_mean": float(np.mean(list(per_partner.values()))) if per_partner else math.nan,
        **per_partner,
        **{key: float(learners.get("__all_modules__", {}).get(key, math.nan)) for key in (MARGINAL_REG_KEY, HEAD_L2_KEY)},
    }


def evaluate(module: Any, setup: EgoSetup, episodes: int, seed: int = 0) -> dict[str, Any]:
    """Per training partner: sampled mean return (and exact, on the bandit); task-module marginal distance."""
    out: dict[str, Any] = {}
    game = setup.population.env
    for e in setup.train:
        r = ego_return(module, setup.head_for(e.name), game, setup.env_config, e.build(), setup.ego_agent, setup.partner_agent, episodes, seed)
        for key, value in r.items():
            out[f"eval/{key}/{e.name}"] = value
    marginals = method(setup.exp.method).marginals
    if has_oracle(game) and marginals is not None:
        obs, mask = marginal_states(setup.population, episodes, seed)
        head = AGG_HEAD_ID if marginals == "network" else None
        for key, value in marginal_distances(module, game, setup.env_config, obs, mask, head).items():
            out[f"eval/marginal_distance/{key}"] = value
    return out


class EgoTrainable(AlgorithmTrainable):
    """One ego-training trial: builds the PPO algorithm, trains it, checkpoints and evaluates it."""

    def setup(self, config: dict[str, Any]) -> None:
        begin = time.perf_counter()
        super().setup(config)
        self.ego = resolve(ExperimentConfig.model_validate(config))
        self.algo = build_ppo_config(self.ego).build_algo()
        maml = self.ego.exp.maml
        self.meta = (
            MetaTrainer(self.algo, [e.name for e in self.ego.train], maml.inner_iterations, maml.outer_step)
            if method(self.ego.exp.method).meta_learned
            else None
        )
        Path(self.logdir, CONFIG_FILE).write_text(yaml.safe_dump(self.ego.exp.model_dump(), sort_keys=False))
        self._start = time.perf_counter()
        self._setup_s = self._start - begin

    def step(self) -> dict[str, Any]:
        metrics = summarize(self.meta.step() if self.meta else self.algo.train(), self.ego)
        metrics["done"] = metrics["env_steps"] >= self.ego.exp.run.timesteps
        if metrics["done"]:
            final = evaluate(self.algo.env_runner.module, self.ego, self.ego.exp.run.eval_episodes, self.ego.exp.seed)
            final["wall_s"] = time.perf_counter() - self._start  # training and evaluation, after setup
            final["setup_s"] = self._setup_s
            Path(self.logdir, EVAL_FILE).write_text(json.dumps(final, indent=2) + "\n")
            metrics.update(final)
        return metrics


def run(
    raw: dict[str, Any], storage: str | Path = "runs", address: str | None = None, progress: str = "lines", resume: bool = False
) -> tune.ResultGrid:
    """Run the experiment `raw` (already validated by `experiment.load`) through Tune; return its results.

    Results go to `storage/<name>/`, with the experiment's config in `experiment.yaml`;
    running the same experiment again continues it (see `tuning.fit` for `progress` and `resume`).
    """
    variants = validate(raw)
    for exp in variants:
        resolve(exp)  # unknown population, wrong seat, bad env config: fail before anything is written
    first = variants[0]
    checkpoint = tune.CheckpointConfig(num_to_keep=first.run.keep_checkpoints, checkpoint_frequency=first.run.checkpoint_every, checkpoint_at_end=True)
    return fit(EgoTrainable, raw, to_param_space(raw), first.name, storage, address, checkpoint, progress, resume)
