"""The one training loop: every pipeline runs its trials through `fit`, a Ray Tune experiment.

`fit` starts a new experiment or, when the experiment folder already exists, continues it
with `Tuner.restore`: finished trials are kept, interrupted ones continue from their last
checkpoint, errored ones are retried. Running the same command again therefore resumes.
"""

from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path
from typing import Any

import ray
import yaml
from ray import tune
from ray.tune import Callback
from ray.tune.execution.placement_groups import PlacementGroupFactory

from rllib_conv.learners.marginal_learner import HEAD_L2_KEY, MARGINAL_REG_KEY


class ProgressLine(Callback):
    """Print one line per trial iteration: steps, returns (mean and worst partner), regulariser, head size, gate."""

    FIELDS = (
        ("return_mean", "return"),
        ("train_return", "return"),
        ("mean_return", "eval"),
        (MARGINAL_REG_KEY, "reg"),
        (HEAD_L2_KEY, "heads"),
        ("gate_check", "gate check"),
        ("gate_score", "gate"),
    )

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        steps = result.get("env_steps", result.get("steps", 0))
        parts = [f"[{trial.trial_id}] iter {result.get('training_iteration', 0):4d}", f"steps {steps:8d}"]
        for key, label in self.FIELDS:
            value = result.get(key)
            if isinstance(value, (int, float)) and not math.isnan(value):
                parts.append(f"{label} {value:.3f}")
            if key == "return_mean":
                returns = [v for k, v in result.items() if k.startswith("return/")]
                if returns:
                    parts.append(f"min {min(returns):.3f}")
        parts.append(f"{result.get('time_total_s', 0.0):7.1f}s")
        print("  ".join(parts), flush=True)


class ProgressTable(Callback):
    """Print a table of every trial (its swept values, status, iteration, steps, return) as the sweep runs.

    Reprinted at most every `every` seconds while results arrive, whenever a trial
    finishes or fails, and once at the end.
    """

    METRICS = (("env_steps", "steps"), ("return_mean", "return"), (MARGINAL_REG_KEY, "reg"))

    def __init__(self, every: float = 30.0) -> None:
        self.every = every
        self._last_print = 0.0

    def table(self, trials: list) -> str:
        """The current table as text: one row per trial."""
        rows = []
        for trial in trials:
            cfg, result = trial.config or {}, trial.last_result or {}
            row = {"trial": trial.trial_id, "status": trial.status}
            # The swept values (grid keys, nested ones as "model/z_dim"), else the usual identifiers.
            swept = getattr(trial, "evaluated_params", None) or {k: cfg.get(k) for k in ("population", "method", "lam", "seed") if k in cfg}
            row.update(swept)
            row["iter"] = result.get("training_iteration", 0)
            for key, label in self.METRICS:
                value = result.get(key)
                row[label] = f"{value:.3f}" if isinstance(value, float) else ("" if value is None else value)
            rows.append(row)
        columns = list(dict.fromkeys(k for row in rows for k in row))
        cells = [[str(row.get(c, "")) for c in columns] for row in rows]
        widths = [max(len(c), *(len(r[i]) for r in cells)) for i, c in enumerate(columns)]
        lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths))]
        lines += ["  ".join(v.rjust(w) for v, w in zip(r, widths)) for r in cells]
        done = sum(t.status == "TERMINATED" for t in trials)
        return "\n".join([f"--- {done}/{len(trials)} trials finished ---", *lines])

    def _print(self, trials: list) -> None:
        self._last_print = time.monotonic()
        print(self.table(trials), flush=True)

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        if time.monotonic() - self._last_print >= self.every:
            self._print(trials)

    def on_trial_complete(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        self._print(trials)

    def on_trial_error(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        self._print(trials)

    def on_experiment_end(self, trials: list, **info: Any) -> None:
        self._print(trials)


PROGRESS = {"lines": ProgressLine, "table": ProgressTable}


RESULT_FILES = ("progress.csv", "result.json")


class TrimRerunResults(Callback):
    """Keep each trial's result files free of repeated iterations after a resume.

    A trial resumed from its checkpoint at iteration k re-runs k+1, k+2, ...; Tune would
    append those rows again. When a result arrives whose iteration is not past the last
    one on disk, the rows from that iteration on are dropped first (this callback runs
    before Tune's loggers write the new row). Works on local (or mounted) storage.
    """

    def __init__(self) -> None:
        self._last: dict[str, int] = {}

    @staticmethod
    def _files(trial: Any) -> list[Path]:
        folders = {Path(p) for p in (getattr(trial, "local_path", None), getattr(trial, "path", None)) if p}
        return [folder / name for folder in folders for name in RESULT_FILES if (folder / name).is_file()]

    @staticmethod
    def _logged(path: Path) -> list[int]:
        if path.suffix == ".csv":
            rows = path.read_text().splitlines()
            if len(rows) < 2:
                return []
            column = rows[0].split(",").index("training_iteration")
            return [int(float(r.split(",")[column])) for r in rows[1:] if r]
        return [json.loads(line)["training_iteration"] for line in path.read_text().splitlines() if line.strip()]

    def _trim(self, path: Path, before: int) -> None:
        lines = path.read_text().splitlines(keepends=True)
        if path.suffix == ".csv":
            keep = lines[:1] + [line for line, it in zip(lines[1:], self._logged(path)) if it < before]
        else:
            keep = [line for line in lines if line.strip() and json.loads(line)["training_iteration"] < before]
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text("".join(keep))
        tmp.replace(path)

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        current = int(result.get("training_iteration", 0))
        if trial.trial_id not in self._last:  # first result since this driver started: ask the disk
            self._last[trial.trial_id] = max((max(self._logged(f), default=0) for f in self._files(trial)), default=0)
        if current <= self._last[trial.trial_id]:
            for path in self._files(trial):
                self._trim(path, before=current)
        self._last[trial.trial_id] = current


def init_ray(address: str | None = None) -> None:
    """Connect to `address` (or $RAY_ADDRESS); without one start a local embedded Ray."""
    if ray.is_initialized():
        return
    # Our trials finish quickly; Tune's warning about slow experiment-state syncs is noise here.
    os.environ.setdefault("TUNE_WARN_EXCESSIVE_EXPERIMENT_CHECKPOINT_SYNC_THRESHOLD_S", "0")
    address = address or os.environ.get("RAY_ADDRESS")
    env = {"env_vars": {"OMP_NUM_THREADS": "1"}}
    if address:
        ray.init(address=address, runtime_env=env, log_to_driver=False)
    else:
        ray.init(include_dashboard=False, runtime_env=env, log_to_driver=False)


def trial_resources(run: dict[str, Any] | None) -> PlacementGroupFactory:
    """What a training trial asks Ray for: a CPU for itself (learner and local env runner),
    one per remote env runner, and the custom resources in `run.resources` (which pin it to
    the nodes that offer them)."""
    run = run or {}
    runners = int(run.get("num_env_runners", 0) or 0)
    return PlacementGroupFactory([{"CPU": 1, **run.get("resources", {})}] + [{"CPU": 1}] * runners)


SPEC_FILE = "experiment.yaml"


def check_spec(folder: Path, spec: dict[str, Any]) -> None:
    """Record `spec` in `folder`, or raise ValueError if the folder holds a different experiment."""
    path = folder / SPEC_FILE
    if path.is_file():
        stored = yaml.safe_load(path.read_text())
        if stored != spec:
            raise ValueError(
                f"{str(folder)!r} already holds a different experiment (see its {SPEC_FILE}); "
                "use another name or storage folder, or delete it to start over"
            )
        return
    folder.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(yaml.safe_dump(spec, sort_keys=False))
    tmp.replace(path)


def fit(
    trainable: type[tune.Trainable],
    spec: dict[str, Any],
    param_space: dict[str, Any],
    name: str,
    storage: str | Path,
    address: str | None = None,
    checkpoint: tune.CheckpointConfig | None = None,
    progress: str = "lines",
    resume: bool = False,
) -> tune.ResultGrid:
    """Run the Tune experiment `storage/name` described by `spec` and return its results.

    If that folder already holds the same experiment (an earlier, possibly interrupted run),
    it is continued instead of started over; a different experiment there is an error, and
    so is `resume=True` with nothing to continue. `progress`: "lines" (one per result) or
    "table" (a table of all trials, see `ProgressTable`).
    """
    if progress not in PROGRESS:
        raise ValueError(f"progress must be one of {sorted(PROGRESS)}, got {progress!r}")
    path = Path(storage).resolve() / name
    restorable = tune.Tuner.can_restore(str(path))
    if resume and not restorable:
        raise ValueError(f"nothing to resume: {str(path)!r} holds no Tune experiment (run without --resume to start it)")
    check_spec(path, spec)
    init_ray(address)
    callbacks = [TrimRerunResults(), PROGRESS[progress]()]
    if restorable:
        tuner = tune.Tuner.restore(str(path), trainable=trainable, param_space=param_space, resume_unfinished=True, resume_errored=True)
        # tuner.pkl holds the first run's callbacks; this run's progress choice (and fixes) win.
        tuner._local_tuner.get_run_config().callbacks = callbacks
    else:
        tuner = tune.Tuner(
            trainable,
            param_space=param_space,
            run_config=tune.RunConfig(
                name=name,
                storage_path=str(path.parent),
                callbacks=callbacks,
                verbose=0,
                # Our config.yaml / eval.json are trial artifacts: persist them with the checkpoints.
                sync_config=tune.SyncConfig(sync_artifacts=True),
                checkpoint_config=checkpoint or tune.CheckpointConfig(checkpoint_at_end=True),
            ),
        )
    return tuner.fit()
