"""The one stage runner: the skeleton the stage pipelines (train, self-play, adapt, zero-shot) share.

A stage runs the configs of one pipeline (one command's, or a whole `reproduce` stage's) as
ONE Tune run, so no core idles between configs. Whatever the pipeline, that is:

1. take every config (checked where it entered: `config_files.Checked`) with what the
   pipeline resolves of it, their names unique, before anything is written (`validated`);
2. share each config's units (seeds, adaptation curves, trained egos, self-play pairs) out
   into jobs, one trial each: units that can be replicas of one algorithm share a trial
   (`packed_jobs`, by `packs.packs`);
3. cut the jobs so they keep every core busy (`packs.spread_over_cores`);
4. name the Tune run (`run_folders.stage_run_name`: the same configs continue the same run);
5. `tuning.fit` it, with one progress line for the whole stage when it has a label
   (`Stage.progress`);
6. gather the trials' tables into one CSV per config (`write_tables`).

`run_jobs` is steps 3-5, `fit_stage` steps 4-5, and `run_packed` steps 2-6 (adapt,
zero-shot). A pipeline supplies only what differs: a `Stage` (its name, Trainable,
checkpoints, which job key lists a trial's units, its table), its units and which may pack
together, and what it makes of the results (train: the experiments it trained; self-play:
a population).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, TypeVar

import pandas as pd
from ray import tune
from ray.tune import Callback

from rllib_conv.common.atomic_files import replaced_atomically
from rllib_conv.common.run_folders import STAGES, stage_run_name
from rllib_conv.partners.population import with_absolute_paths
from rllib_conv.training.callbacks import StageProgress
from rllib_conv.training.packs import cluster_cpus, packs, spread_over_cores
from rllib_conv.training.tuning import fit, job_param_space, job_units, trial_job

T = TypeVar("T")
C = TypeVar("C")
R = TypeVar("R")

# A packed job (`packed_jobs`): the index of its config among the stage's, and that config.
JOB_INDEX = "index"
JOB_CONFIG = "config"


@dataclass(frozen=True)
class Table:
    """The table every trial of a stage writes into its folder, and how one config's are gathered into one CSV."""

    file: str  # in each trial folder
    columns: list[str]  # the CSV's columns, in order
    order: list[str]  # the keys its rows are sorted by
    what: str  # how a failed pack is named in the error ("adaptation", "zero-shot")


@dataclass(frozen=True)
class Stage:
    """What one pipeline's stage is, apart from its units (see the module docstring)."""

    name: str  # one of `run_folders.STAGES`: names its Tune runs
    trainable: type[tune.Trainable]
    checkpoint: tune.CheckpointConfig
    units: str | None = None  # the job key listing the units a trial runs together; None: a trial is one unit
    first_key: str | None = None  # a job key set to its own first unit when a cut splits the job (`spread_over_cores`)
    stops_early: str | None = None  # why a trial may end before its steps are played (`StageProgress`)
    table: Table | None = None  # what `run_packed` gathers
    manifest_key: str = "population"  # the config key holding a manifest path, made absolute for the trials

    def __post_init__(self) -> None:
        if self.name not in STAGES:
            raise ValueError(f"stage: expected one of {list(STAGES)}, got {self.name!r}")

    def progress(self, label: str | None) -> str | Callback:
        """One `StageProgress` line for the whole stage under `label`; without a label, one line per result."""
        if not label:
            return "lines"
        units = partial(job_units, key=self.units) if self.units else None
        return StageProgress(label, units=units, stops_early=self.stops_early)

    def run_name(self, names: list[str], spec: Any) -> str:
        """The Tune run of this stage for the configs `names`, described by `spec` (`run_folders.stage_run_name`)."""
        return stage_run_name(self.name, names, spec)


def validated(configs: list[R], check: Callable[[R], C], what: str) -> list[C]:
    """Every config of `configs` as `check` returns it (it raises ValueError on a bad one); ValueError unless their names differ.

    `what` names the configs in that error ("adapt", "zero-shot").
    """
    cfgs = [check(config) for config in configs]
    names = [cfg.name for cfg in cfgs]  # type: ignore[attr-defined]
    if len(set(names)) < len(names):
        raise ValueError(f"{what} configs must have different names; got {names}")
    return cfgs


def configs_spec(raws: list[dict[str, Any]], names: list[str]) -> Any:
    """What a stage of the configs `raws` records as its experiment (`tuning.check_spec`): the one config itself, or all of them with their names."""
    return raws[0] if len(raws) == 1 else {"experiments": names, "configs": raws}


def packed_jobs(
    stage: Stage, raws: list[dict[str, Any]], cfgs: list[Any], units: list[list[T]], key: Callable[[int, T], Hashable], cpus: int
) -> list[dict[str, Any]]:
    """The units of every config in packs, one job a pack: `{"index": i, "config": raws[i], <stage.units>: pack}`.

    The units of config i (`units[i]`) pack by equal `key(i, unit)`, at most the config's
    `max_pack` a pack and about as many packs as `cpus` over the whole stage (`packs.packs`).
    """
    total = sum(map(len, units))
    return [
        # Manifest paths made absolute: Tune runs every trial in its own folder.
        {JOB_INDEX: i, JOB_CONFIG: with_absolute_paths(raw, stage.manifest_key), stage.units: pack}
        for i, (raw, cfg, some) in enumerate(zip(raws, cfgs, units))
        for pack in packs(some, partial(key, i), cpus, cfg.max_pack, total)
    ]


def fit_stage(
    stage: Stage,
    spec: Any,
    param_space: dict[str, Any],
    names: list[str],
    storage: str | Path,
    address: str | None = None,
    label: str | None = None,
    loggers: Sequence[str] = (),
) -> tune.ResultGrid:
    """Run the stage's Tune run over `param_space` (named by `Stage.run_name`, recording `spec`) and return its results.

    Run again with the same configs it continues (`tuning.fit`); an interrupted run raises
    `tuning.StageInterrupted`, so no caller takes it for a finished one.
    """
    name = stage.run_name(names, spec)
    return fit(
        stage.trainable, spec, param_space, name, storage, address, stage.checkpoint, stage.progress(label), loggers=loggers
    )


def run_jobs(
    stage: Stage,
    spec: Any,
    jobs: list[dict[str, Any]],
    names: list[str],
    storage: str | Path,
    address: str | None = None,
    label: str | None = None,
    loggers: Sequence[str] = (),
    cpus: int | None = None,
) -> tune.ResultGrid:
    """Cut `jobs` (each listing its units under `stage.units`) to keep the cluster's `cpus` cores busy, then `fit_stage` them, one trial a job."""
    if stage.units is None:
        raise ValueError(f"stage {stage.name!r}: jobs need the key of their units (Stage.units)")
    jobs = spread_over_cores(jobs, stage.units, cpus or cluster_cpus(address), stage.first_key)
    return fit_stage(stage, spec, job_param_space(jobs), names, storage, address, label, loggers)


def run_packed(
    stage: Stage,
    raws: list[dict[str, Any]],
    cfgs: list[Any],
    units: list[list[T]],
    key: Callable[[int, T], Hashable],
    out: str | Path,
    storage: str | Path,
    address: str | None = None,
    label: str | None = None,
    loggers: Sequence[str] = (),
) -> dict[str, pd.DataFrame]:
    """Run the units of the validated configs `cfgs` (`raws` as given) in packs, as one Tune run; write and return each config's table by name.

    One config's run is `<stage>-<name>`, several configs' `<stage>-stage-<hash>`
    (`run_folders.stage_run_name`); see `packed_jobs` for `units` and `key`, `write_tables`
    for the CSVs in `out`.
    """
    if stage.table is None:
        raise ValueError(f"stage {stage.name!r}: run_packed needs the table its trials write (Stage.table)")
    cpus = cluster_cpus(address)
    names = [cfg.name for cfg in cfgs]
    jobs = packed_jobs(stage, raws, cfgs, units, key, cpus)
    results = run_jobs(stage, configs_spec(raws, names), jobs, names, storage, address, label, loggers, cpus)
    return write_tables(results, cfgs, stage.table, Path(out))


def write_tables(results: Any, cfgs: list[Any], table: Table, out: Path) -> dict[str, pd.DataFrame]:
    """Gather the packs' tables (`table.file` in each trial folder) of a stage's Tune `results` into one CSV per config; return them by name.

    Every trial's config is a job with the `index` of its config in `cfgs`. A config whose
    packs all finished gets `out/<name>.csv` (written whole, then moved into place); one with
    a failed pack gets none, and RuntimeError names them after the others are written.
    """
    parts: list[list[pd.DataFrame]] = [[] for _ in cfgs]
    failed = [0] * len(cfgs)
    for result in results:
        index, path = trial_job(result.config)[JOB_INDEX], Path(result.path) / table.file
        if result.error or not path.is_file():
            failed[index] += 1
        else:
            parts[index].append(pd.read_csv(path)[table.columns])
    out.mkdir(parents=True, exist_ok=True)
    tables = {}
    for cfg, frames, errors in zip(cfgs, parts, failed):
        if errors:  # no CSV: a config's CSV means all its rows are in it
            continue
        rows = pd.concat(frames, ignore_index=True).sort_values(table.order, kind="stable", ignore_index=True)
        with replaced_atomically(out / f"{cfg.name}.csv") as tmp:
            rows.to_csv(tmp, index=False)
        tables[cfg.name] = rows
    if any(failed):
        unfinished = [c.name for c, n in zip(cfgs, failed) if n]
        raise RuntimeError(
            f"{sum(failed)} {table.what} pack(s) failed, so {unfinished} wrote no CSV; run again to retry them (finished packs are kept)"
        )
    return tables
