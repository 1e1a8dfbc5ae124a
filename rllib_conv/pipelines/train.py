"""Train the modular ego through Ray Tune: one experiment config (grids allowed) -> one Tune run.

Each trial is an `EgoTrainable` wrapping one RLlib PPO algorithm. The seeds of a trial's
grid point train together in it as replicas (`rllib_conv.training.algorithm.Replica`):
one game copy and one set of modules per seed, each seeded from its seed alone, so every
seed trains as it would alone while the env runner and learner costs are paid once.

A `reproduce` or `train` stage packs further: every experiment whose egos can be replicas of one
algorithm (the same game, partner count, method and sizes; `algorithm.packing_key`, which lets
the regulariser's and the head penalty's weights differ per replica) trains in one trial, e.g.
a lambda sweep over several populations of one game; each replica is still exported to its own
experiment's folder and trains as it would alone (`experiment_packs`).

The Tune trial folder holds Tune's `params.json`/`progress.csv` (per-iteration metrics:
the replicas' mean, and each replica's under `seed=<s>/...`) and its checkpoints (the whole
algorithm, for resuming). When training ends each replica is written as an ordinary
trained-ego folder `<trial>/seed=<s>/` (`replica_export`): `config.yaml`, `progress.csv`,
a sealed checkpoint of its modules and, last, `eval.json` (final per-partner returns and
marginal distances).
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from ray import tune
from ray.tune.search.variant_generator import generate_variants

from rllib_conv.common.config_files import GRID_KEY, Checked, is_grid
from rllib_conv.common.methods import method
from rllib_conv.common.run_folders import EVAL_FILE, REPLICA_PREFIX, TRAIN, replica_folder
from rllib_conv.envs.oracles import has_oracle
from rllib_conv.learners.marginal_learner import HEAD_L2_KEY, MARGINAL_REG_KEY
from rllib_conv.modules.multi import AGG_HEAD_ID, TASK_ID, partner_id, replica_id
from rllib_conv.partners.population import team_name, with_absolute_paths
from rllib_conv.training.algorithm import Replica, build_algorithm, packing_key
from rllib_conv.training.callbacks import STEPS_DONE, STEPS_TOTAL
from rllib_conv.training.ego_setup import EgoSetup, resolve
from rllib_conv.training.evaluate import ego_head_partner, seated_return
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.maml import MetaTrainer
from rllib_conv.training.marginal_distance import marginal_distances, marginal_states
from rllib_conv.training.replica_export import export_replica, replica_module, seat_head_modules
from rllib_conv.training.replica_steps import replica_env_steps
from rllib_conv.training.stage import Stage, run_jobs, validated
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.tuning import check_spec, fit, to_param_space
from rllib_conv.training.weights import learner_module

REPLICA_SEEDS = "replica_seeds"  # a trial config's seeds, trained together as replicas
EXPORT_KEY = "export_to"  # a stage job's folder for its replicas (default: its Tune trial folder)
MEMBERS = "members"  # a stage trial's experiments: [{"config": one grid point's config, "export_to": its egos' folder}]
REPLICAS = "replicas"  # a stage trial's replicas: [[member index, seed], ...]
# Replicas in one trial at most: more share the per-step costs further, but every replica's rollouts and
# modules live in the one process.
MAX_REPLICAS = 32
HISTORY_FILE = "replica_history.json"  # in a trial checkpoint: every replica's progress rows so far


def summarize(result: dict[str, Any], setup: EgoSetup, replica: int) -> dict[str, Any]:
    """Replica `replica`'s part of RLlib's result dict: its env steps, returns per partner (per team of partners where
    there are several partner seats; the one head's for BaselineAgg there), regulariser, head size."""
    module_returns = result.get("env_runners", {}).get("module_episode_returns_mean", {})
    if len(setup.partner_agents) == 1:
        # The partner module's return: the ego's, whichever head (or the one head) played.
        played = {e.name: partner_id(e.name) for e in setup.train}
    else:
        # A partner in two seats sums both seats' returns in its module's: the ego's head per team says the team's.
        played = {team_name(t): setup.head_for(t) for t in setup.teams}
    modules = {name: replica_id(mid, replica) for name, mid in played.items()}
    per_partner = {f"return/{name}": float(module_returns[mid]) for name, mid in modules.items() if mid in module_returns}
    learners = result.get("learners", {}).get(replica_id(TASK_ID, replica), {})
    return {
        "env_steps": replica_env_steps(result, replica),
        "return_mean": float(np.mean(list(per_partner.values()))) if per_partner else math.nan,
        **per_partner,
        **{key: float(learners.get(key, math.nan)) for key in (MARGINAL_REG_KEY, HEAD_L2_KEY)},
    }


def evaluate(module: Any, setup: EgoSetup, episodes: int, seed: int = 0) -> dict[str, Any]:
    """Per training partner (or team of them): sampled mean return (and exact, on the bandit); task-module marginal distance."""
    out: dict[str, Any] = {}
    game = setup.population.env
    entries = {e.name: e for e in setup.train}
    for team in setup.teams:  # each training partner alone; one per partner seat where there are several
        players = {setup.ego_agent: ego_head_partner(module, setup.head_for(team))}
        players |= {agent: entries[name].build() for agent, name in zip(setup.partner_agents, team)}
        for key, value in seated_return(players, game, setup.env_config, episodes, seed).items():
            out[f"eval/{key}/{team_name(team)}"] = value
    marginals = method(setup.exp.method).marginals
    if has_oracle(game) and marginals is not None:
        obs, mask = marginal_states(setup.population, episodes, seed)
        head = AGG_HEAD_ID if marginals == "network" else None
        for key, value in marginal_distances(module, game, setup.env_config, obs, mask, head).items():
            out[f"eval/marginal_distance/{key}"] = value
    return out


def trial_members(config: dict[str, Any]) -> tuple[list[dict[str, Any]], list[tuple[int, int]]]:
    """A training trial's experiments (`{"config", "export_to"}`, None: the trial folder) and replicas ((member, seed)).

    A stage job lists them (`MEMBERS`, `REPLICAS`); a `run` trial is one experiment's grid
    point, its seeds in `replica_seeds`, exported to the trial's own folder.
    """
    if MEMBERS in config:
        return [dict(m) for m in config[MEMBERS]], [(int(i), int(s)) for i, s in config[REPLICAS]]
    point = {k: v for k, v in config.items() if k not in (REPLICA_SEEDS, EXPORT_KEY)}
    seeds = list(config.get(REPLICA_SEEDS) or [config.get("seed", 0)])
    return [{"config": point, "export_to": config.get(EXPORT_KEY)}], [(0, int(s)) for s in seeds]


def _mean_over(rows: list[dict[str, Any]]) -> dict[str, float]:
    """Each key's mean over the replicas' rows that have it (replicas of several populations name other partners)."""
    keys = dict.fromkeys(key for row in rows for key in row)
    return {key: float(np.mean([row[key] for row in rows if key in row])) for key in keys}


def _member_name(export: Path) -> str:
    """How a trial of several experiments names one in its metrics: `<experiment>/<point>`."""
    return f"{export.parent.name}/{export.name}"


class EgoTrainable(AlgorithmTrainable):
    """One ego-training trial: its replicas (seeds, of one experiment or several) train in one PPO algorithm, are
    evaluated and exported when done."""

    def _exports(self, members: list[dict[str, Any]]) -> list[Path]:
        return [Path(m.get("export_to") or self.trial_folder) for m in members]

    def outputs_complete(self, config: dict[str, Any]) -> bool:
        members, units = trial_members(config)
        exports = self._exports(members)
        return all((replica_folder(exports[i], s) / EVAL_FILE).is_file() for i, s in units)

    def build(self, config: dict[str, Any]) -> None:
        members, units = trial_members(config)
        self.exports = self._exports(members)
        exps = {i: ExperimentConfig.model_validate(members[i]["config"]) for i in sorted({i for i, _ in units})}
        self.units = units
        self.replicas = [Replica(resolve(exps[i].model_copy(update={"seed": s}))) for i, s in units]
        # Metric prefixes: `seed=<s>/` in a trial of one experiment, `<experiment>/<point>/seed=<s>/` in one of several.
        self.labels = [
            f"{REPLICA_PREFIX}{s}" if len(members) == 1 else f"{_member_name(self.exports[i])}/{REPLICA_PREFIX}{s}"
            for i, s in units
        ]
        self.algo = build_algorithm(self.replicas)
        exp = self.replicas[0].setup.exp
        maml = exp.maml
        self.meta = (
            MetaTrainer(self.algo, [e.name for e in self.replicas[0].setup.train], maml.inner_iterations, maml.outer_step)
            if method(exp.method).meta_learned
            else None
        )
        self.history: list[list[dict[str, Any]]] = [[] for _ in units]

    def advance(self) -> dict[str, Any]:
        with self.timings.measure("iterate"):
            result = self.meta.step() if self.meta else self.algo.train()
        rows = [summarize(result, rep.setup, r) for r, rep in enumerate(self.replicas)]
        for history, row in zip(self.history, rows):
            history.append({"training_iteration": self.iteration + 1, **row})
        metrics = _mean_over(rows)
        metrics["env_steps"] = min(row["env_steps"] for row in rows)
        for label, row in zip(self.labels, rows):
            metrics.update({f"{label}/{k}": v for k, v in row.items()})
        budget = self.replicas[0].setup.exp.run.timesteps
        metrics["done"] = metrics["env_steps"] >= budget
        metrics[STEPS_DONE] = sum(min(row["env_steps"], budget) for row in rows)
        metrics[STEPS_TOTAL] = budget * len(rows)
        if metrics["done"]:
            with self.timings.measure("evaluate"):
                metrics.update(self._finish())
        return metrics

    def _finish(self) -> dict[str, float]:
        """Evaluate every replica and export it as a trained-ego folder `<export>/seed=<s>/`; return the evaluations
        (each replica's under its label, their mean under the plain keys) and the trial's training time (`wall_s`, `setup_s`)."""
        module = learner_module(self.algo)
        timing = {
            "wall_s": self.timings.seconds["iterate"],
            "setup_s": self.timings.seconds["setup"],
        }  # training, before the evaluations
        evaluations = []
        for r, rep in enumerate(self.replicas):
            plain = replica_module(module, r, rep)
            final = evaluate(plain, rep.setup, rep.setup.exp.run.eval_episodes, rep.own_seed)
            evaluations.append(final)
            final = {**final, **timing, "replicas": len(self.replicas)}
            folder = replica_folder(self.exports[self.units[r][0]], rep.own_seed)
            export_replica(plain, rep, folder, final, self.history[r], seat_head_modules(module, r, rep))
        out = _mean_over(evaluations) | timing
        for label, e in zip(self.labels, evaluations):
            out.update({f"{label}/{k}": v for k, v in e.items()})
        return out

    def save_extra(self, checkpoint_dir: Path) -> None:
        (checkpoint_dir / HISTORY_FILE).write_text(json.dumps(self.history))

    def load_extra(self, checkpoint_dir: Path) -> None:
        path = checkpoint_dir / HISTORY_FILE
        if path.is_file():
            self.history = json.loads(path.read_text())


def replica_param_space(raw: dict[str, Any]) -> dict[str, Any]:
    """The Tune param space of an experiment: its grids, except that its seeds become one trial's replicas.

    `seed: {grid_search: [0, 1, 2]}` (or a single seed) trains as one trial per point of the
    other grids, with `replica_seeds: [0, 1, 2]`.
    """
    seed = raw.get("seed", 0)
    seeds = seed[GRID_KEY] if is_grid(seed) else [seed]
    return to_param_space({**{k: v for k, v in raw.items() if k != "seed"}, "seed": seeds[0], REPLICA_SEEDS: list(seeds)})


def run(
    config: Checked[ExperimentConfig],
    storage: str | Path = "runs",
    address: str | None = None,
    progress: str = "lines",
    resume: bool = False,
    loggers: Sequence[str] = (),
) -> tune.ResultGrid:
    """Run the experiment `config` (checked: `experiment.load`, `experiment.checked`) through Tune; return its results.

    Results go to `storage/<name>/`, with the experiment's config in `experiment.yaml`;
    running the same experiment again continues it (see `tuning.fit` for `progress`,
    `resume` and `loggers`).
    """
    first = _resolved(config)
    raw = config.raw
    return fit(
        EgoTrainable,
        raw,
        replica_param_space(with_absolute_paths(raw, "population")),
        first.name,
        storage,
        address,
        _checkpoints(first),
        progress,
        resume,
        loggers,
    )


def _resolved(config: Checked[ExperimentConfig]) -> ExperimentConfig:
    """The experiment's first variant, after resolving every variant: unknown population, wrong seat, bad env config fail
    before anything is written."""
    for exp in config.variants:
        resolve(exp)
    return config.first


def _checkpoints(exp: ExperimentConfig) -> tune.CheckpointConfig:
    return tune.CheckpointConfig(
        num_to_keep=exp.run.keep_checkpoints, checkpoint_frequency=exp.run.checkpoint_every, checkpoint_at_end=True
    )


def training_jobs(raw: dict[str, Any], folder: Path) -> list[dict[str, Any]]:
    """The trials of experiment `raw` as stage jobs: one per point of its grids (its seeds as replicas),
    exporting its egos to `folder/point_<i>/seed=<s>/`."""
    # Manifest paths made absolute: Tune runs every trial in its own folder.
    points = [spec for _, spec in generate_variants(replica_param_space(with_absolute_paths(raw, "population")))]
    return [{**point, EXPORT_KEY: str(folder / f"point_{i}")} for i, point in enumerate(points)]


def _unfinished(job: dict[str, Any]) -> dict[str, Any] | None:
    """`job` narrowed to its seeds not trained yet (None when all are): more seeds than an earlier run train only the new ones."""
    seeds = [s for s in job[REPLICA_SEEDS] if not (replica_folder(Path(job[EXPORT_KEY]), s) / EVAL_FILE).is_file()]
    return {**job, "seed": seeds[0], REPLICA_SEEDS: seeds} if seeds else None


def experiment_packs(jobs: list[dict[str, Any]], max_replicas: int = MAX_REPLICAS) -> list[dict[str, Any]]:
    """`jobs` (`training_jobs`, narrowed to their unfinished seeds) as stage jobs of whole packs: the seeds of every job
    whose egos can be replicas of one algorithm (`algorithm.packing_key`) share one, at most `max_replicas` a job.

    A job is `{MEMBERS: [{"config", "export_to"}], REPLICAS: [[member, seed], ...]}` (plus the members' `run`
    settings, which Tune's resource request reads). First-order MAML's outer steps focus every replica on its own k-th
    training partner, so its egos of several populations pack too.
    """
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for job in jobs:
        point = {k: v for k, v in job.items() if k not in (REPLICA_SEEDS, EXPORT_KEY)}
        member = {"config": point, "export_to": job[EXPORT_KEY], "seeds": job[REPLICA_SEEDS]}
        groups[packing_key(resolve(ExperimentConfig.model_validate(point)))].append(member)
    out = []
    for group in groups.values():
        members = [{"config": m["config"], "export_to": m["export_to"]} for m in group]
        units = [[i, s] for i, m in enumerate(group) for s in m["seeds"]]
        run = {"run": members[0]["config"]["run"]} if "run" in members[0]["config"] else {}
        for n in range(math.ceil(len(units) / max_replicas)):
            out.append({**run, MEMBERS: members, REPLICAS: units[n * max_replicas : (n + 1) * max_replicas]})
    return out


def train_stage(
    configs: list[Checked[ExperimentConfig]],
    storage: str | Path,
    address: str | None = None,
    label: str = "train",
    loggers: Sequence[str] = (),
) -> list[str]:
    """Train every experiment of `configs` (checked) in one Tune run (its trials spread over the cluster); return the experiments trained now.

    Each experiment's egos land where `run` puts them, `storage/<name>/<point>/seed=<s>/`,
    with its config in `storage/<name>/experiment.yaml` (a different experiment there is an
    error). Egos already trained are skipped (an experiment with more seeds than an earlier
    run trains the new seeds only). The Tune run itself is
    `storage/train-stage-<hash>/`, named after every job of `configs`: run again after an
    interruption it continues (finished trials kept, interrupted ones from their checkpoints).
    """
    storage = Path(storage).resolve()
    exps = validated(configs, _resolved, "train")
    jobs, names = [], [exp.name for exp in exps]
    for config, exp in zip(configs, exps):
        check_spec(storage / exp.name, config.raw, grows="seed")  # more seeds later: the new ones train, the rest are kept
        jobs += training_jobs(config.raw, storage / exp.name)
    todo = [left for job in jobs if (left := _unfinished(job))]
    if not todo:
        return []
    stage = Stage(TRAIN, EgoTrainable, _checkpoints(exps[0]), units=REPLICAS)
    spec = {"experiments": names, "jobs": jobs}  # every job, trained or not: the same experiments continue the same run
    results = run_jobs(stage, spec, experiment_packs(todo), names, storage, address, label, loggers)
    if results.errors:
        raise RuntimeError(f"{len(results.errors)} training trial(s) failed; see {storage / stage.run_name(names, spec)}")
    return sorted({Path(job[EXPORT_KEY]).parent.name for job in todo})
