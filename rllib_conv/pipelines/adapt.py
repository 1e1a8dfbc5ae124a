"""Adapt trained egos to new partners: keep the task module, add a fresh head, train with lam 0.

Every (trained ego, new partner) pair is one Tune trial (`AdaptTrainable`): the ego is
rebuilt from the run's resolved config with the new partner as its only partner, the
task module's weights (and, for single-network methods, the head's) load from the run's
last checkpoint, and the ego is evaluated before every update. All methods go through
this one pipeline; `scratch` starts from a fresh single network instead. With
`head_init: pick` the first `pick_steps` env steps try the fresh head and each training
partner's head on the new partner instead of training, and the best one's weights start
the new head (`head_pick`).

Output: one tidy CSV, one row per evaluation point: run, method, lam, z_dim, seed,
partner, steps, mean_return, stderr, exact_return (one-step games only).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pandas as pd
from ray import tune

from rllib_conv import envs, partners
from rllib_conv.common.config_files import validate
from rllib_conv.common.methods import method
from rllib_conv.common.run_folders import ADAPT_PREFIX, RL_MODULE_DIR, trial_folders
from rllib_conv.envs.defaults import ADAPT_DEFAULTS
from rllib_conv.modules.multi import AGG_HEAD_ID, TASK_ID
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.ego_setup import EgoSetup, setup_for
from rllib_conv.training.evaluate import ego_head_partner, ego_return, load_module
from rllib_conv.training.experiment import ExperimentConfig, trial_config
from rllib_conv.training.head_pick import HeadPick, pick_head
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.tuning import fit
from rllib_conv.training.weights import load_weights, push_learner_weights

PAIR_KEY = "adapt_pair"
STEPS_FILE = "adapt_steps.json"
FRESH = "fresh"  # the new partner's own (fresh) head, as a `head_pick` candidate
PICK_SEED = 1_000_000  # head-picking episodes are seeded apart from the evaluation episodes
CURVE_COLUMNS = ["run", "method", "lam", "z_dim", "seed", "partner", "steps", "mean_return", "stderr", "exact_return"]


def adapt_setup(cfg: AdaptConfig) -> tuple[EgoSetup, dict[str, str], ExperimentConfig]:
    """The ego setup adapting run `cfg.run` to partner `cfg.partner`, the weights to load, the run's config."""
    trial = Path(cfg.run)
    trained = trial_config(trial)
    pop = partners.get(cfg.population or trained.population)
    entry = next((e for e in pop.partners if e.name == cfg.partner), None)
    if entry is None:
        raise ValueError(f"population {pop.name!r} has no partner {cfg.partner!r}; it has {[e.name for e in pop.partners]}")
    game = trained.env
    if pop.env != game:
        raise ValueError(f"population {pop.name!r} is for {pop.env!r}, but the ego in {str(trial)!r} was trained on {game!r}")
    if cfg.head_init == "pick" and method(trained.method).single_head:
        raise ValueError(
            f"head_init 'pick' needs one head per training partner, but the ego in {str(trial)!r} was trained with "
            f"method {trained.method!r} (one shared head)"
        )
    defaults = ADAPT_DEFAULTS.get(game, {"every": trained.ppo.rollout_per_partner, "steps": 20 * trained.ppo.rollout_per_partner})
    every = cfg.every or defaults["every"]
    ppo = trained.ppo.model_dump()
    ppo.update({"rollout_per_partner": every, **{k: defaults[k] for k in ("minibatch_size", "num_epochs") if k in defaults}, **cfg.ppo})
    scratch = cfg.method == "scratch"
    exp = trained.model_copy(
        update={
            "lam": 0.0,
            "head_l2": 0.0,
            "method": "agg" if scratch else trained.method,
            "freeze": [] if cfg.train_task else ["task"],
            "ppo": type(trained.ppo).model_validate(ppo),
            "env_config": {**pop.env_config},
        }
    )
    checkpoint = last_checkpoint(trial) / RL_MODULE_DIR
    load = {} if scratch else {TASK_ID: str(checkpoint / TASK_ID)}
    if method(exp.method).single_head and not scratch:
        load[AGG_HEAD_ID] = str(checkpoint / AGG_HEAD_ID)
    return setup_for(exp, pop, [entry]), load, trained


class AdaptTrainable(AlgorithmTrainable):
    """One adaptation curve: evaluate, update, evaluate, ... until `steps` env steps."""

    def setup(self, config: dict[str, Any]) -> None:
        super().setup(config)
        self.cfg = AdaptConfig.model_validate({**{k: v for k, v in config.items() if k != PAIR_KEY}, **config.get(PAIR_KEY, {})})
        self.ego, load, trained = adapt_setup(self.cfg)
        defaults = ADAPT_DEFAULTS.get(self.ego.population.env, {})
        self.total = self.cfg.steps or defaults.get("steps", 20 * self.ego.exp.ppo.rollout_per_partner)
        self.algo = build_ppo_config(self.ego, load).build_algo()
        self.label = {
            "run": self.cfg.run,
            "method": self.cfg.method or trained.method,
            "lam": trained.lam,
            "z_dim": trained.model.z_dim or trained.model.hidden,
            "seed": trained.seed,
            "partner": self.cfg.partner,
        }
        self.steps = 0
        self.offset = 0  # env steps spent picking the head, before the first update
        self.picked: str | None = None

    def _pick_head(self) -> HeadPick:
        """Try the fresh head and every trained head on the new partner; copy the winner into the new head."""
        entry, new_head = self.ego.train[0], self.ego.head_for(self.ego.train[0].name)
        trained = load_module(last_checkpoint(self.cfg.run))
        seed = self.cfg.seed + PICK_SEED
        players = {FRESH: ego_head_partner(self.algo.env_runner.module, new_head, seed)}
        players |= {mid: ego_head_partner(trained, mid, seed) for mid in trained.head_ids()}
        game, env_config = self.ego.population.env, self.ego.env_config
        budget = self.cfg.pick_steps or self.ego.exp.ppo.rollout_per_partner
        pick = pick_head(lambda: envs.make(game, **env_config), players, entry.build, self.ego.ego_agent, self.ego.partner_agent, budget, seed)
        if pick.chosen != FRESH:
            weights = {new_head: trained[pick.chosen].state_dict()}
            self.algo.learner_group.foreach_learner(lambda learner: load_weights(learner.module, weights))
            push_learner_weights(self.algo)
        self.offset = max(pick.steps, budget)
        return pick

    def step(self) -> dict[str, Any]:
        entry = self.ego.train[0]
        r = ego_return(
            self.algo.env_runner.module,
            self.ego.head_for(entry.name),
            self.ego.population.env,
            self.ego.env_config,
            entry.build(),
            self.ego.ego_agent,
            self.ego.partner_agent,
            self.cfg.episodes,
            seed=self.cfg.seed + self.iteration,
        )
        row = {**self.label, "steps": self.steps, "mean_return": r["mean"], "stderr": r["stderr"], "exact_return": r.get("exact", math.nan)}
        done = self.steps >= self.total
        if not done and self.cfg.head_init == "pick" and self.picked is None:
            self.picked = self._pick_head().chosen
            self.steps = self.offset
        elif not done:
            self.steps = self.offset + int(self.algo.train()["env_runners"]["num_env_steps_sampled_lifetime"])
        return {**row, "done": done, **({"picked": self.picked} if self.picked else {})}

    def save_extra(self, checkpoint_dir: Path) -> None:
        (checkpoint_dir / STEPS_FILE).write_text(json.dumps({"steps": self.steps, "offset": self.offset, "picked": self.picked}))

    def load_extra(self, checkpoint_dir: Path) -> None:
        saved = json.loads((checkpoint_dir / STEPS_FILE).read_text())
        self.steps, self.offset, self.picked = saved["steps"], saved.get("offset", 0), saved.get("picked")


def adaptation_trials(cfg: AdaptConfig) -> list[dict[str, str]]:
    """Every (run, partner) pair to adapt, validated before anything runs."""
    pairs = []
    for run in cfg.runs:
        for trial in trial_folders(run):
            last_checkpoint(trial)
            trained = trial_config(trial)
            pop = partners.get(cfg.population or trained.population)
            names = cfg.partners or [e.name for e in pop.entries(cfg.split)]
            unknown = set(names) - {e.name for e in pop.partners}
            if unknown:
                raise ValueError(f"population {pop.name!r} has no partner(s) {sorted(unknown)}")
            pairs += [{"run": str(trial.resolve()), "partner": name} for name in names]
    if not pairs:
        raise ValueError(f"no partners to adapt to (split {cfg.split!r} is empty)")
    return pairs


def run_adaptation(raw: dict[str, Any], out: str | Path = "adaptation", storage: str | Path = "runs", address: str | None = None) -> pd.DataFrame:
    """Adapt every run in `raw` to every chosen partner; write and return the tidy curves CSV."""
    cfg = validate(raw, schema=AdaptConfig)[0]
    pairs = adaptation_trials(cfg)
    for pair in pairs:
        adapt_setup(AdaptConfig.model_validate({**raw, **pair}))  # wrong game, missing weights: fail early
    # One trial per (run, partner) pair; Tune grids cannot zip two axes, so the pair is one value.
    results = fit(AdaptTrainable, raw, {**raw, PAIR_KEY: tune.grid_search(pairs)}, f"{ADAPT_PREFIX}{cfg.name}", storage, address)
    frames = [r.metrics_dataframe[CURVE_COLUMNS] for r in results if r.metrics_dataframe is not None and not r.error]
    curves = pd.concat(frames, ignore_index=True).sort_values(["run", "partner", "steps"]) if frames else pd.DataFrame(columns=CURVE_COLUMNS)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    curves.to_csv(out / f"{cfg.name}.csv", index=False)
    if results.errors:
        raise RuntimeError(f"{len(results.errors)} adaptation trial(s) failed; the others are in {out / (cfg.name + '.csv')}")
    return curves
