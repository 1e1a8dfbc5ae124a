"""The one training loop: every pipeline runs its trials through `fit`, a Ray Tune experiment.

`fit` starts a new experiment or, when the experiment folder already exists, continues it
with `Tuner.restore`: finished trials are kept, interrupted ones continue from their last
checkpoint, errored ones are retried. Running the same command again therefore resumes.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import ray
import yaml
from ray import tune
from ray.tune import Callback

from rllib_conv.learners.marginal_learner import MARGINAL_REG_KEY


class ProgressLine(Callback):
    """Print one line per trial iteration: steps, returns (mean and worst partner), regulariser, gate."""

    FIELDS = (
        ("return_mean", "return"),
        ("train_return", "return"),
        ("mean_return", "eval"),
        (MARGINAL_REG_KEY, "reg"),
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
) -> tune.ResultGrid:
    """Run the Tune experiment `storage/name` described by `spec` and return its results.

    If that folder already holds the same experiment (an earlier, possibly interrupted run),
    it is continued instead of started over; a different experiment there is an error.
    """
    path = Path(storage).resolve() / name
    check_spec(path, spec)
    init_ray(address)
    if tune.Tuner.can_restore(str(path)):
        tuner = tune.Tuner.restore(str(path), trainable=trainable, param_space=param_space, resume_unfinished=True, resume_errored=True)
    else:
        tuner = tune.Tuner(
            trainable,
            param_space=param_space,
            run_config=tune.RunConfig(
                name=name,
                storage_path=str(path.parent),
                callbacks=[ProgressLine()],
                verbose=0,
                # Our config.yaml / eval.json are trial artifacts: persist them with the checkpoints.
                sync_config=tune.SyncConfig(sync_artifacts=True),
                checkpoint_config=checkpoint or tune.CheckpointConfig(checkpoint_at_end=True),
            ),
        )
    return tuner.fit()
