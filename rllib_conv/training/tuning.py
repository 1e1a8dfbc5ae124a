"""The one training loop: every pipeline runs its trials through `fit`, a Ray Tune experiment.

`fit` starts a new experiment or, when the experiment folder already exists, continues it
with `Tuner.restore`: finished trials are kept, interrupted ones continue from their last
checkpoint, errored ones are retried. Running the same command again therefore resumes.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import ray
import yaml
from ray import tune
from ray.tune import Callback
from ray.tune.execution.placement_groups import PlacementGroupFactory
from ray.tune.utils import flatten_dict

from rllib_conv.common.atomic_files import write_text_atomically
from rllib_conv.common.config_files import GRID_KEY
from rllib_conv.common.run_folders import SPEC_FILE, spec_digest
from rllib_conv.common.tracking import LOGGERS
from rllib_conv.training.callbacks import PROGRESS, KeepLogsAtCheckpoints, TrimRerunResults, restore_checkpointed_logs
from rllib_conv.training.surviving_checkpoint import ResumeFromSurvivingCheckpoint

# A stage's Tune run (`job_param_space`): every trial's config is one job under this key.
JOB_KEY = "job"


def logger_callbacks(loggers: Sequence[str], folder: Path, name: str) -> list[Callback]:
    """Tune logger callbacks for `loggers` (`rllib_conv.common.tracking.LOGGERS`), writing under the experiment folder `folder`.

    `wandb` runs offline unless $WANDB_MODE says otherwise (files in `folder/wandb/`, to
    `wandb sync` later); `mlflow` keeps a local file store in `folder/mlruns/`.
    ValueError for an unknown logger or a missing package.
    """
    callbacks: list[Callback] = []
    for kind in loggers:
        if kind not in LOGGERS:
            raise ValueError(f"--log: expected one of {list(LOGGERS)}, got {kind!r}")
        if kind == "tensorboard":
            continue
        try:
            if kind == "wandb":
                from ray.air.integrations.wandb import WandbLoggerCallback  # optional dependency (extra 'tracking')

                folder.mkdir(parents=True, exist_ok=True)
                # Ray asks for an API key unless the environment says offline (or disabled).
                os.environ.setdefault("WANDB_MODE", "offline")
                callbacks.append(WandbLoggerCallback(project=name, dir=str(folder), mode=os.environ["WANDB_MODE"]))
            else:
                # A file store needs no server or database; MLflow 3 asks for this to allow one.
                os.environ.setdefault("MLFLOW_ALLOW_FILE_STORE", "true")
                callbacks.append(_mlflow_logger((folder / "mlruns").resolve().as_uri(), name))
        except ImportError as exc:
            raise ValueError(
                f"--log {kind}: the {kind} package is not installed (pip install 'rllib-conv[tracking]'): {exc}"
            ) from None
    return callbacks


def _mlflow_logger(uri: str, name: str) -> Callback:
    """Tune's MLflow callback, with metric names MLflow accepts: a replica's 'seed=0/x' is logged as 'seed:0/x'."""
    from ray.air.integrations.mlflow import MLflowLoggerCallback  # optional dependency (extra 'tracking')

    class MLflowLogger(MLflowLoggerCallback):
        def log_trial_result(self, iteration: int, trial, result: dict) -> None:
            flat = flatten_dict(result, delimiter="/")
            super().log_trial_result(iteration, trial, {k.replace("=", ":"): v for k, v in flat.items()})

    return MLflowLogger(tracking_uri=uri, experiment_name=name)


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


def to_param_space(raw: Any) -> Any:
    """Replace `{grid_search: [...]}` nodes of a raw config by `tune.grid_search`."""
    if isinstance(raw, dict):
        if set(raw) == {GRID_KEY}:
            return tune.grid_search(raw[GRID_KEY])
        return {k: to_param_space(v) for k, v in raw.items()}
    return raw


def job_param_space(jobs: list[dict[str, Any]]) -> dict[str, Any]:
    """The param space of a Tune run whose trials are `jobs` (one config each), however different they are."""
    return {JOB_KEY: tune.grid_search(list(jobs))}


def trial_job(config: dict[str, Any]) -> dict[str, Any]:
    """A trial's own config: its job in a `job_param_space` run, else the config itself."""
    return config[JOB_KEY] if JOB_KEY in config else config


def job_units(config: dict[str, Any], key: str) -> int:
    """How many units (seeds, curves, runs) the trial with `config` runs together: the length of its job's `key`.

    For `StageProgress(units=partial(job_units, key=...))`.
    """
    return len(trial_job(config)[key])


def spec_name(prefix: str, spec: Any) -> str:
    """A Tune experiment name for `spec` that only the same spec gets again: `<prefix><12 hex digits>` (`run_folders.spec_digest`)."""
    return f"{prefix}{spec_digest(spec)}"


def _grid_values(value: Any) -> list[Any]:
    """The values a config entry stands for: a grid's list, or the one value."""
    return list(value[GRID_KEY]) if isinstance(value, dict) and GRID_KEY in value else [value]


def check_spec(folder: Path, spec: dict[str, Any], grows: str | None = None) -> None:
    """Record `spec` in `folder`, or raise ValueError if the folder holds a different experiment.

    `grows`: a top-level key (the seeds) whose values may differ from the recorded spec's:
    the experiment is the same with more (or fewer) of them, and the record keeps them all.
    """
    path = folder / SPEC_FILE
    if path.is_file():
        stored = yaml.safe_load(path.read_text())
        if stored == spec:
            return
        same = grows is not None and {k: v for k, v in stored.items() if k != grows} == {
            k: v for k, v in spec.items() if k != grows
        }
        if not same:
            raise ValueError(
                f"{str(folder)!r} already holds a different experiment (see its {SPEC_FILE}); "
                "use another name or storage folder, or delete it to start over"
            )
        values = sorted({*_grid_values(stored.get(grows)), *_grid_values(spec.get(grows))} - {None})
        spec = {**spec, grows: {GRID_KEY: values}}
        if spec == stored:
            return
    folder.mkdir(parents=True, exist_ok=True)
    write_text_atomically(path, yaml.safe_dump(spec, sort_keys=False))


class StageInterrupted(KeyboardInterrupt):
    """A Tune run stopped by Ctrl-C (Tune saves and stops the trials, then returns as if done), or with trials unfinished."""


def _second_ctrl_c(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


@contextmanager
def _noticing_ctrl_c() -> Iterator[list[bool]]:
    """Yield a flag that says, after the block, whether Ctrl-C stopped the Tune run inside it.

    On SIGINT Tune's own handler stops the run gracefully and puts back the handler it found
    (`ray.tune.tune._setup_signal_catching`); it tells no one. Had every trial just finished,
    the stage would pass for done and the next stage start: the Ctrl-C lost. So the handler
    Tune finds is ours: a second Ctrl-C still raises, and finding ours back means Tune fired.
    """
    fired = [False]
    if threading.current_thread() is not threading.main_thread():
        yield fired  # only the main thread has signal handlers (and Tune installs none there)
        return
    before = signal.signal(signal.SIGINT, _second_ctrl_c)
    try:
        yield fired
        fired[0] = signal.getsignal(signal.SIGINT) is _second_ctrl_c and not os.getenv("TUNE_DISABLE_SIGINT_HANDLER")
    finally:
        signal.signal(signal.SIGINT, before)


def fit(
    trainable: type[tune.Trainable],
    spec: dict[str, Any],
    param_space: dict[str, Any],
    name: str,
    storage: str | Path,
    address: str | None = None,
    checkpoint: tune.CheckpointConfig | None = None,
    progress: str | Callback = "lines",
    resume: bool = False,
    loggers: Sequence[str] = (),
) -> tune.ResultGrid:
    """Run the Tune experiment `storage/name` described by `spec` and return its results.

    If that folder already holds the same experiment (an earlier, possibly interrupted run),
    it is continued instead of started over; a different experiment there is an error, and
    so is `resume=True` with nothing to continue. `progress`: "lines" (one per result),
    "table" (a table of all trials, see `ProgressTable`) or a Tune callback of its own
    (`StageProgress`). `loggers` adds experiment tracking (`logger_callbacks`).

    Raises `StageInterrupted` when Ctrl-C stopped the run or trials neither finished nor failed,
    so that no caller takes an interrupted run for a finished one (and, e.g., marks its stage done).
    """
    if not isinstance(progress, Callback) and progress not in PROGRESS:
        raise ValueError(f"progress must be one of {sorted(PROGRESS)}, got {progress!r}")
    path = Path(storage).resolve() / name
    restorable = tune.Tuner.can_restore(str(path))
    if resume and not restorable:
        raise ValueError(f"nothing to resume: {str(path)!r} holds no Tune experiment (run without --resume to start it)")
    check_spec(path, spec)
    init_ray(address)
    callbacks = [
        TrimRerunResults(),
        KeepLogsAtCheckpoints(),
        ResumeFromSurvivingCheckpoint(),
        progress if isinstance(progress, Callback) else PROGRESS[progress](),
        *logger_callbacks(loggers, path, name),
    ]
    if restorable:
        restore_checkpointed_logs(path)
        tuner = tune.Tuner.restore(
            str(path), trainable=trainable, param_space=param_space, resume_unfinished=True, resume_errored=True
        )
        # tuner.pkl holds the first run's callbacks; this run's progress choice (and fixes) win.
        tuner._local_tuner.get_run_config().callbacks = callbacks
    else:
        tuner = tune.Tuner(
            trainable,
            param_space=param_space,
            # One worker runs trial after trial (`AlgorithmTrainable.reset_config`) instead of a new process per trial.
            tune_config=tune.TuneConfig(reuse_actors=True),
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
    with _noticing_ctrl_c() as ctrl_c:
        results = tuner.fit()
    # Tune marks interrupted trials TERMINATED too; a finished one's last result says `done` (every trainable here sets it).
    finished = sum(r.error is not None or bool((r.metrics or {}).get("done")) for r in results)
    if ctrl_c[0] or finished < len(results):
        raise StageInterrupted(
            f"{finished} of {len(results)} trials of {str(path)!r} finished; run the same command again to continue the others"
            if finished < len(results)
            else f"{finished} of {len(results)} trials of {str(path)!r} finished before Ctrl-C; run the same command again to go on"
        )
    return results
