"""Zero-shot coordination on a new task with known partners: the paper's three steps, trained egos in packs.

1. Heads for the test partners, on the old task, task module frozen.
2. The task module re-trained on the new task, paired with the training partners' heads
   (frozen) and the run's regulariser weight.
3. The new task module composed with the test partners' heads from step 1, evaluated on
   the new task with the test partners (who keep their conventions), without training.

Egos run the steps in packs, as replicas of one algorithm (`packs`), one Tune trial a pack;
several zero-shot configs (a `reproduce` stage) run as one Tune run. A pack writes its rows
(`zeroshot.csv` in its trial folder) when it finishes.

Output: one row per (run, test partner): zero-shot mean return, its standard error and,
on the bandit, the exact expected return.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from pathlib import Path
from typing import Any

import pandas as pd
import torch
from ray import tune

from rllib_conv import envs, partners
from rllib_conv.common import methods
from rllib_conv.common.atomic_files import replaced_atomically
from rllib_conv.common.config_files import Checked
from rllib_conv.common.run_folders import RL_MODULE_DIR, ZEROSHOT, trial_folders
from rllib_conv.common.seeds import stream_seed
from rllib_conv.modules.mlp import mlp, seeded_generator
from rllib_conv.modules.multi import TASK_ID, ego_id
from rllib_conv.modules.packed.ego_stack import TASK_LOGITS_LAYER
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig
from rllib_conv.training.algorithm import Replica, build_algorithm, packing_key
from rllib_conv.training.callbacks import STEPS_DONE, STEPS_TOTAL
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.ego_setup import setup_for
from rllib_conv.training.evaluate import ego_head_partner, player_return
from rllib_conv.training.experiment import ExperimentConfig, trial_config
from rllib_conv.training.replica_export import replica_module
from rllib_conv.training.replica_steps import replica_env_steps
from rllib_conv.training.settings import MappingSettings
from rllib_conv.training.stage import Stage, Table, run_packed, validated
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.weights import learner_module, push_learner_weights

RESULT_COLUMNS = ["run", "method", "lam", "seed", "partner", "mean_return", "stderr", "exact_return"]
RESULTS_FILE = "zeroshot.csv"  # a finished pack's rows, in its trial folder
RESULTS_TABLE = Table(RESULTS_FILE, RESULT_COLUMNS, order=["run", "partner"], what="zero-shot")


def zeroshot_plan(cfg: ZeroShotConfig, run: str | Path) -> dict[str, Any]:
    """Check the trained ego in folder `run` can be composed and gather what the three steps need."""
    trial = Path(run)
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
    defaults = envs.game(trained.env).zeroshot_defaults(trained.ppo.rollout_per_partner, trained.run.timesteps)
    return {
        "trained": trained,
        "old": old,
        "new": new,
        "checkpoint": last_checkpoint(trial) / RL_MODULE_DIR,
        "head_steps": cfg.head_steps or defaults.head_steps,
        "task_steps": cfg.task_steps or defaults.task_steps,
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
    round_robin = MappingSettings()  # the paper's protocol, whatever mapping the run trained with
    return {
        "heads": trained.model_copy(update={"lam": weight(cfg.head_lam), "freeze": ["task"], "mapping": round_robin}),
        "task": trained.model_copy(
            update={
                "mapping": round_robin,
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
    """The three zero-shot steps for a pack of trained egos (replicas of one algorithm); one RLlib iteration per Tune step.

    Its config is a job (`job_param_space`): `config`, the zero-shot config, and `runs`,
    the trained-ego folders of the pack.
    """

    def outputs_complete(self, config: dict[str, Any]) -> bool:
        return (self.trial_folder / RESULTS_FILE).is_file()

    def build(self, config: dict[str, Any]) -> None:
        job = config
        self.cfg = ZeroShotConfig.model_validate(job["config"])
        self.runs = list(job["runs"])
        self.plans = [zeroshot_plan(self.cfg, run) for run in self.runs]
        self.head_replicas = [
            Replica(setup_for(p["heads"], p["old"], p["old"].entries("test")), {TASK_ID: str(p["checkpoint"] / TASK_ID)})
            for p in self.plans
        ]
        self.algo = build_algorithm(self.head_replicas)
        self.phase, self.composed = 1, []

    def _start_task_phase(self) -> None:
        module = learner_module(self.algo)
        # Test heads (and the old task module, replaced at evaluation) of each ego, as plain modules.
        self.composed = [replica_module(module, r, rep) for r, rep in enumerate(self.head_replicas)]
        self.algo.stop()
        self.task_replicas = []
        for p in self.plans:
            new, ckpt = p["new"], p["checkpoint"]
            load = {TASK_ID: str(ckpt / TASK_ID), **{ego_id(e.name): str(ckpt / ego_id(e.name)) for e in new.entries("train")}}
            self.task_replicas.append(Replica(setup_for(p["task"], new, new.entries("train")), load))
        self.algo = build_algorithm(self.task_replicas)
        if self.cfg.reset_task_logits:
            # Forget the old rules, keep the representation z the conventions are read from.
            fresh = [
                reset_logits_state(learner_module(self.algo)[STACK_ID].task_state(r), rep.own_seed)
                for r, rep in enumerate(self.task_replicas)
            ]

            def reset(learner: Any) -> None:
                for r, state in enumerate(fresh):
                    learner.module[STACK_ID].load_task(r, state)

            self.algo.learner_group.foreach_learner(reset)
            push_learner_weights(self.algo)
        self.phase = 2

    def _evaluate(self) -> list[dict[str, Any]]:
        """One row per (ego, test partner): the new task module with that partner's head from step 1, on the new task."""
        stack, rows = learner_module(self.algo)[STACK_ID], []
        for r, (run, plan, composed) in enumerate(zip(self.runs, self.plans, self.composed)):
            composed[TASK_ID].load_state_dict(stack.task_state(r))
            new, trained, setup = plan["new"], plan["trained"], self.task_replicas[r].setup
            for entry in new.entries("test"):
                score = player_return(
                    ego_head_partner(composed, ego_id(entry.name)),
                    new.env,
                    new.env_config,
                    entry.build(),
                    setup.ego_agent,
                    setup.partner_agent,
                    self.cfg.episodes,
                    self.cfg.seed,
                )
                rows.append(
                    {
                        "run": run,
                        "method": trained.method,
                        "lam": trained.lam,
                        "seed": trained.seed,
                        "partner": entry.name,
                        "mean_return": score["mean"],
                        "stderr": score["stderr"],
                        "exact_return": score.get("exact", math.nan),
                    }
                )
        return rows

    def advance(self) -> dict[str, Any]:
        with self.timings.measure("iterate"):
            result = self.algo.train()
        replicas = self.head_replicas if self.phase == 1 else self.task_replicas
        steps = [replica_env_steps(result, r) for r in range(len(replicas))]
        returns = [v for k, v in result["env_runners"].get("module_episode_returns_mean", {}).items() if k.startswith("partner@")]
        head_steps, task_steps = self.plans[0]["head_steps"], self.plans[0]["task_steps"]
        done_steps = (
            sum(min(s, head_steps) for s in steps)
            if self.phase == 1
            else len(steps) * head_steps + sum(min(s, task_steps) for s in steps)
        )
        out: dict[str, Any] = {
            "phase": self.phase,
            "env_steps": min(steps),
            "return_mean": sum(returns) / len(returns) if returns else math.nan,
            STEPS_DONE: done_steps,
            STEPS_TOTAL: len(steps) * (head_steps + task_steps),
        }
        if self.phase == 1 and min(steps) >= head_steps:
            with self.timings.measure("setup"):
                self._start_task_phase()
        elif self.phase == 2 and min(steps) >= task_steps:
            with self.timings.measure("evaluate"):
                self._write_results(self._evaluate())
            out["done"] = True
        return out

    def _write_results(self, rows: list[dict[str, Any]]) -> None:
        with replaced_atomically(self.trial_folder / RESULTS_FILE) as tmp:
            pd.DataFrame(rows, columns=RESULT_COLUMNS).to_csv(tmp, index=False)


def reset_logits_state(task_state: dict[str, torch.Tensor], seed: int) -> dict[str, torch.Tensor]:
    """A task module state with its task-logits layer re-initialised as a fresh module's (seeded from `seed`)."""
    weight = task_state[f"{TASK_LOGITS_LAYER}.weight"]
    fresh = mlp(
        [weight.shape[1], weight.shape[0]], out_gain=0.01, generator=seeded_generator(stream_seed(seed, "task_logits_reset"))
    )
    return {
        **task_state,
        f"{TASK_LOGITS_LAYER}.weight": fresh[0].weight.detach(),
        f"{TASK_LOGITS_LAYER}.bias": fresh[0].bias.detach(),
    }


def run_zeroshots(
    configs: list[Checked[ZeroShotConfig]],
    out: str | Path = "zeroshot",
    storage: str | Path = "runs",
    address: str | None = None,
    label: str | None = None,
    loggers: Sequence[str] = (),
) -> dict[str, pd.DataFrame]:
    """Run the three steps for every run of every zero-shot config in `configs` (checked), in one Tune run; write and return each config's table by name.

    One row per (run, test partner). One config runs as the Tune experiment `zeroshot-<name>`,
    several as `zeroshot-stage-<hash>`; `label` names the stage in its progress line.
    """
    cfgs = validated(configs, lambda config: config.first, "zero-shot")
    runs = [[str(t.resolve()) for run in cfg.runs for t in trial_folders(run)] for cfg in cfgs]
    plans = {
        (i, run): zeroshot_plan(cfg, run) for i, (cfg, rs) in enumerate(zip(cfgs, runs)) for run in rs
    }  # not modular, no new-task partners: fail early

    def key(i: int, run: str) -> Hashable:
        plan = plans[(i, run)]
        return packing_key(setup_for(plan["heads"], plan["old"], plan["old"].entries("test")))

    stage = Stage(
        ZEROSHOT,
        ZeroShotTrainable,
        tune.CheckpointConfig(checkpoint_at_end=False),
        units="runs",
        table=RESULTS_TABLE,
        manifest_key="new_population",
    )
    return run_packed(stage, [config.raw for config in configs], cfgs, runs, key, out, storage, address, label, loggers)


def run_zeroshot(
    config: Checked[ZeroShotConfig],
    out: str | Path = "zeroshot",
    storage: str | Path = "runs",
    address: str | None = None,
    loggers: Sequence[str] = (),
) -> pd.DataFrame:
    """Run the three steps for every run of the zero-shot config `config` (checked); write and return one row per (run, test partner)."""
    return next(iter(run_zeroshots([config], out, storage, address, loggers=loggers).values()))
