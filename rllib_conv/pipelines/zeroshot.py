"""Zero-shot coordination on a new task with known partners: the paper's three steps, one Tune trial per run.

1. Heads for the test partners, on the old task, task module frozen.
2. The task module re-trained on the new task, paired with the training partners' heads
   (frozen) and the run's regulariser weight.
3. The new task module composed with the test partners' heads from step 1, evaluated on
   the new task with the test partners (who keep their conventions), without training.

Output: one row per (run, test partner): zero-shot mean return, its standard error and,
on the bandit, the exact expected return.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd
from ray import tune

from rllib_conv import partners
from rllib_conv.common import methods
from rllib_conv.common.config_files import validate
from rllib_conv.common.run_folders import RL_MODULE_DIR, ZEROSHOT_PREFIX, trial_folders
from rllib_conv.envs.defaults import ZEROSHOT_DEFAULTS
from rllib_conv.modules.mlp import mlp
from rllib_conv.modules.multi import TASK_ID, ego_id
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.ego_setup import setup_for
from rllib_conv.training.evaluate import ego_return
from rllib_conv.training.experiment import ExperimentConfig, trial_config
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.tuning import fit
from rllib_conv.training.weights import push_learner_weights

RESULT_COLUMNS = ["run", "method", "lam", "seed", "partner", "mean_return", "stderr", "exact_return"]


def zeroshot_plan(cfg: ZeroShotConfig) -> dict[str, Any]:
    """Check the run can be composed and gather what the three steps need."""
    trial = Path(cfg.run)
    trained = trial_config(trial)
    composable = tuple(methods.names(composable=True))
    if trained.method not in composable:
        raise ValueError(f"method {trained.method!r} is not modular: zero-shot composition needs one of {composable}")
    old = partners.get(trained.population)
    new = partners.get(cfg.new_population or f"{old.name}-newtask")
    for split in ("train", "test"):
        missing = {e.name for e in old.entries(split)} - {e.name for e in new.entries(split)}
        if missing:
            raise ValueError(f"new-task population {new.name!r} lacks the {split} partners {sorted(missing)} of {old.name!r}")
    defaults = ZEROSHOT_DEFAULTS.get(trained.env, {"head_steps": 10 * trained.ppo.rollout_per_partner, "task_steps": trained.run.timesteps})
    return {
        "trained": trained,
        "old": old,
        "new": new,
        "checkpoint": last_checkpoint(trial) / RL_MODULE_DIR,
        "head_steps": cfg.head_steps or defaults["head_steps"],
        "task_steps": cfg.task_steps or defaults["task_steps"],
        **step_experiments(trained, cfg),
    }


def step_experiments(trained: ExperimentConfig, cfg: ZeroShotConfig) -> dict[str, ExperimentConfig]:
    """Return the ego settings of step 1 (`heads`: test heads, old task) and step 2 (`task`: task module, new task).

    Both regulariser weights default to the run's lam; they apply to runs with learned task
    logits (`modular`) only, the others have none to regularise and keep 0. Step 1 keeps
    the run's head penalty (test heads trained like the training heads); step 2 drops it,
    since its heads are frozen and the penalty would only bend z to shrink them.
    """

    def weight(lam: float | None) -> float:
        return (trained.lam if lam is None else lam) if methods.method(trained.method).regularised else 0.0

    ppo = trained.ppo.model_copy(update={"entropy_coeff": cfg.task_entropy})
    return {
        "heads": trained.model_copy(update={"lam": weight(cfg.head_lam), "freeze": ["task"]}),
        "task": trained.model_copy(
            update={
                "freeze": ["heads"],
                "ppo": ppo,
                "env_config": {},
                "lam": weight(cfg.task_lam),
                "z_lr_scale": cfg.task_z_lr_scale,
                "head_l2": 0.0,
            }
        ),
    }


class ZeroShotTrainable(AlgorithmTrainable):
    """The three zero-shot steps for one trained ego; one RLlib iteration per Tune step."""

    def setup(self, config: dict[str, Any]) -> None:
        super().setup(config)
        self.cfg = ZeroShotConfig.model_validate(config)
        self.plan = zeroshot_plan(self.cfg)
        old, ckpt = self.plan["old"], self.plan["checkpoint"]
        self.heads_setup = setup_for(self.plan["heads"], old, old.entries("test"))
        self.algo = build_ppo_config(self.heads_setup, {TASK_ID: str(ckpt / TASK_ID)}).build_algo()
        self.phase, self.phase_steps, self.composed = 1, 0, None

    def _start_task_phase(self) -> None:
        new, ckpt = self.plan["new"], self.plan["checkpoint"]
        self.composed = self.algo.env_runner.module  # test heads (and the old task module, replaced below)
        self.algo.stop()
        self.task_setup = setup_for(self.plan["task"], new, new.entries("train"))
        load = {TASK_ID: str(ckpt / TASK_ID), **{ego_id(e.name): str(ckpt / ego_id(e.name)) for e in new.entries("train")}}
        self.algo = build_ppo_config(self.task_setup, load).build_algo()
        if self.cfg.reset_task_logits:
            # Forget the old rules, keep the representation z the conventions are read from.
            def reset(learner: Any) -> None:
                layer = learner.module[TASK_ID].pi_out
                fresh = mlp([layer[0].in_features, layer[0].out_features], out_gain=0.01)
                layer.load_state_dict(fresh.state_dict())

            self.algo.learner_group.foreach_learner(reset)
            push_learner_weights(self.algo)
        self.phase, self.phase_steps = 2, 0

    def _evaluate(self) -> dict[str, Any]:
        self.composed[TASK_ID].set_state(self.algo.env_runner.module[TASK_ID].get_state())
        new, trained = self.plan["new"], self.plan["trained"]
        out = {}
        for entry in new.entries("test"):
            r = ego_return(
                self.composed, ego_id(entry.name), new.env, new.env_config, entry.build(), self.task_setup.ego_agent,
                self.task_setup.partner_agent, self.cfg.episodes, self.cfg.seed,
            )
            out[f"zeroshot/{entry.name}"] = {"mean_return": r["mean"], "stderr": r["stderr"], "exact_return": r.get("exact", math.nan)}
        return {"method": trained.method, "lam": trained.lam, "seed": trained.seed, **out}

    def step(self) -> dict[str, Any]:
        result = self.algo.train()
        runners = result["env_runners"]
        self.phase_steps = int(runners["num_env_steps_sampled_lifetime"])
        returns = [v for k, v in runners.get("module_episode_returns_mean", {}).items() if k.startswith("partner@")]
        out: dict[str, Any] = {"phase": self.phase, "env_steps": self.phase_steps, "return_mean": sum(returns) / len(returns) if returns else math.nan}
        if self.phase == 1 and self.phase_steps >= self.plan["head_steps"]:
            self._start_task_phase()
        elif self.phase == 2 and self.phase_steps >= self.plan["task_steps"]:
            out.update(self._evaluate())
            out["done"] = True
        return out


def run_zeroshot(raw: dict[str, Any], out: str | Path = "zeroshot", storage: str | Path = "runs", address: str | None = None) -> pd.DataFrame:
    """Run the three steps for every run in `raw`; write and return one row per (run, test partner)."""
    cfg = validate(raw, schema=ZeroShotConfig)[0]
    trials = [str(t.resolve()) for run in cfg.runs for t in trial_folders(run)]
    for trial in trials:
        zeroshot_plan(cfg.model_copy(update={"run": trial}))  # not modular, no new-task partners: fail early
    results = fit(
        ZeroShotTrainable,
        raw,
        {**raw, "run": tune.grid_search(trials)},
        f"{ZEROSHOT_PREFIX}{cfg.name}",
        storage,
        address,
        tune.CheckpointConfig(checkpoint_at_end=False),
    )
    rows = []
    for r in results:
        if r.error or not r.metrics:
            continue
        m = r.metrics
        for key, value in m.items():
            if key.startswith("zeroshot/"):
                rows.append({"run": r.config["run"], "method": m["method"], "lam": m["lam"], "seed": m["seed"], "partner": key.split("/", 1)[1], **value})
    table = pd.DataFrame(rows, columns=RESULT_COLUMNS)
    Path(out).mkdir(parents=True, exist_ok=True)
    table.to_csv(Path(out) / f"{cfg.name}.csv", index=False)
    if results.errors:
        raise RuntimeError(f"{len(results.errors)} zero-shot trial(s) failed; the others are in {Path(out) / (cfg.name + '.csv')}")
    return table
