"""The run-folder layout: which file every run, trial, stage and reproduction keeps where.

Writers (the pipelines) and readers (`analysis`, `adapt`, `play`, ...) both name files
through this module, so the layout is written down once:

    <storage>/<experiment>/            one Tune experiment (`rllib-conv train`, `sweep`, a stage)
        experiment.yaml                the experiment as given (grids kept)
        <trial>/progress.csv           Tune's per-iteration metrics (result.json alike)
        <trial>/checkpoint_<n>/        sealed RLlib checkpoints of the whole algorithm (for resuming)
        <trial>/seed=<s>/              one trained ego (a replica of the trial; older runs: the trial itself):
            config.yaml                its resolved config
            progress.csv               its per-iteration metrics
            checkpoint_000000/         its sealed modules, under learner_group/learner/rl_module/
            eval.json                  its final evaluation (written last)

    <reproduce out>/<game>/            one game of `rllib-conv reproduce`
        plan.json                      the plan that ran (game, seeds, quick, train_steps, stages), the game's report facts
        <stage>.done                   a finished stage: "<seconds> s", then one covered item a line
        runs/<population>__<label>/    trained egos: <grid point>/seed=<s>/ as above, experiment.yaml
        runs/train-stage-<hash>/       the train stage's Tune run (its trials' checkpoints); adapt-stage-<hash>/,
                                       zeroshot-stage-<hash>/, selfplay-<name>/: those of later stages
        populations/<name>/            self-play populations (population.json, selfplay_report.csv)
        adaptation/<name>.csv          adaptation curves
        zeroshot/<name>.csv            zero-shot results
        marginals.csv                  task-module distances to the true marginals
        superseded/<time>/             outputs a `--redo` moved aside
"""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path
from typing import Any

from rllib_conv.common.atomic_files import write_text_atomically
from rllib_conv.common.config_files import read_yaml
from rllib_conv.common.file_versions import FileVersion, read_once
from rllib_conv.common.sealed import verify_file

# --- one Tune experiment and its trials -------------------------------------------------
SPEC_FILE = "experiment.yaml"
CONFIG_FILE = "config.yaml"
EVAL_FILE = "eval.json"
PROGRESS_FILES = ("progress.csv", "result.json")
CHECKPOINT_PREFIX = "checkpoint_"
# Inside an RLlib algorithm checkpoint: one folder per module ID.
RL_MODULE_DIR = Path("learner_group") / "learner" / "rl_module"
# Inside an exported ego with one head per partner seat and partner (`model.heads: seat`): each seat head as a plain
# head checkpoint of its own (`ego@<seat>=<partner>`), beside the team heads that sum them.
SEAT_HEADS_DIR = "seat_heads"

# --- populations --------------------------------------------------------------------------
POPULATION_FILE = "population.json"
SELFPLAY_REPORT_FILE = "selfplay_report.csv"
SELFPLAY_TRIAL_FILE = "selfplay.json"  # one self-play pair's outcome, in its trial folder

# --- the stages and their Tune runs ---------------------------------------------------------
# The stages of a reproduction, in order; all but `marginals` run as one Tune run each.
SELFPLAY, TRAIN, ADAPT, ZEROSHOT, MARGINALS, HELDOUT = "selfplay", "train", "adapt", "zeroshot", "marginals", "heldout"
EVALUATE = "evaluate"  # the field's protocol: trained egos against the game's evaluation sets (no Tune run)
STAGES: tuple[str, ...] = (SELFPLAY, TRAIN, ADAPT, ZEROSHOT, MARGINALS, HELDOUT, EVALUATE)
# One self-play, adapt or zero-shot config runs as the Tune run `<stage>-<name>`; several (a
# `reproduce` stage) as one Tune run `<stage>-stage-<hash of their spec>`, whose trials write
# their results into each config's own outputs. The train stage's run is always the latter:
# `<name>/` is the experiment's own folder, where its egos go.
STAGE_RUN_INFIX = "stage-"
ADAPT_PREFIX = f"{ADAPT}-"  # adaptation `name` runs as the Tune experiment `adapt-<name>`
ZEROSHOT_PREFIX = f"{ZEROSHOT}-"
SELFPLAY_PREFIX = f"{SELFPLAY}-"
TRAIN_STAGE_PREFIX = f"{TRAIN}-{STAGE_RUN_INFIX}"
# What marks a Tune run of a stage, never an experiment of trained egos.
STAGE_PREFIXES: tuple[str, ...] = (ADAPT_PREFIX, ZEROSHOT_PREFIX, SELFPLAY_PREFIX, TRAIN_STAGE_PREFIX)

# --- a reproduction's game folder ---------------------------------------------------------
PLAN_FILE = "plan.json"
RUNS_DIR = "runs"
POPULATIONS_DIR = "populations"
ADAPTATION_DIR = "adaptation"
ZEROSHOT_DIR = "zeroshot"
CROSSPLAY_DIR = "crossplay"
USER_STUDY_DIR = "user_study"
SUPERSEDED_DIR = "superseded"
MARGINALS_FILE = "marginals.csv"
# The columns `marginals.csv` is written with (`pipelines.marginal_report`), also when it has no rows.
MARGINALS_FILE_COLUMNS = (
    "run",
    "env",
    "env_config",
    "population",
    "method",
    "lam",
    "z_dim",
    "seed",
    "distance",
    "distance_all_states",
    "states",
)
HELDOUT_FILE = "heldout.csv"  # the held-out evaluation: one row per (agent, seed, partner)
EVALUATION_DIR = "evaluation"  # `<population>__<set role>/`: `rllib-conv evaluate`'s scores.csv, summary.json, summary.png
MARKER_SUFFIX = ".done"
# What marks a folder as one game of a reproduction.
GAME_MARKERS: tuple[str, ...] = (PLAN_FILE, RUNS_DIR, ADAPTATION_DIR, ZEROSHOT_DIR, MARGINALS_FILE, POPULATIONS_DIR)
EXPERIMENT_SEPARATOR = "__"


def experiment_name(population: str, label: str) -> str:
    """The name of a reproduction's experiment: `<population>__<label>` (population by its folder name)."""
    return f"{Path(population).name}{EXPERIMENT_SEPARATOR}{label}"


def split_experiment(name: str) -> tuple[str, str]:
    """Split an experiment or file stem `<population>__<label>` into (population, label); no `__` gives (name, "")."""
    population, sep, label = name.partition(EXPERIMENT_SEPARATOR)
    return (population, label) if sep else (name, "")


REPLICA_PREFIX = "seed="


def replica_folder(trial: Path, seed: int) -> Path:
    """Where the trained ego of seed `seed` of Tune trial folder `trial` is exported."""
    return trial / f"{REPLICA_PREFIX}{seed}"


def experiment_of(trial: str | Path) -> Path:
    """The experiment folder of a trained-ego folder (a replica's is two levels up, an older trial's one)."""
    trial = Path(trial)
    return trial.parent.parent if trial.name.startswith(REPLICA_PREFIX) else trial.parent


def trial_name(trial: str | Path) -> str:
    """A trained ego's name, unique within its experiment: `<Tune trial>/seed=<s>` (older runs: the trial folder's name)."""
    trial = Path(trial)
    return f"{trial.parent.name}/{trial.name}" if trial.name.startswith(REPLICA_PREFIX) else trial.name


def trial_folders(path: str | Path, missing_ok: bool = False) -> list[Path]:
    """The trained-ego folders under `path` (itself, or every one of an experiment folder, replicas included).

    ValueError when `path` holds neither, unless `missing_ok` (then an empty list: an
    experiment whose training has not begun, e.g. one a killed run set up).
    """
    path = Path(path)
    if (path / CONFIG_FILE).is_file():
        return [path]
    trials = sorted(
        p.parent for pattern in (f"*/{CONFIG_FILE}", f"*/{REPLICA_PREFIX}*/{CONFIG_FILE}") for p in path.glob(pattern)
    )
    if not trials and not missing_ok:
        raise ValueError(
            f"{str(path)!r} is neither a trained-ego trial folder nor an experiment folder holding some ({CONFIG_FILE} missing)"
        )
    return trials


def read_trial_config(trial: str | Path) -> dict[str, Any]:
    """A trial's resolved config (its `config.yaml`) as a plain dict (a copy of its own); ValueError naming the file when it
    differs from what was saved or is not YAML.

    A stage reads each trained ego's config once per curve it adapts: the file is parsed once per version of it.
    """
    return copy.deepcopy(read_once(Path(trial) / CONFIG_FILE, _read_trial_config, _TRIAL_CONFIGS))


_TRIAL_CONFIGS: dict[FileVersion, dict[str, Any]] = {}


def _read_trial_config(path: Path) -> dict[str, Any]:
    verify_file(path, "trial config")
    return read_yaml(path, "trial config") or {}


def checkpoints(trial: str | Path) -> list[Path]:
    """The trial's checkpoint folders, oldest first."""
    return sorted(Path(trial).glob(f"{CHECKPOINT_PREFIX}*"), key=lambda p: int(p.name.rsplit("_", 1)[1]))


def spec_digest(spec: Any) -> str:
    """12 hex digits that only the same spec (a JSON-able dict, keys in any order) gets again."""
    return hashlib.sha1(json.dumps(spec, sort_keys=True, default=str).encode()).hexdigest()[:12]


def stage_run_prefix(stage: str) -> str:
    """How the Tune runs of several configs of stage `stage` begin: `<stage>-stage-`."""
    return f"{stage}-{STAGE_RUN_INFIX}"


def stage_run_name(stage: str, names: list[str], spec: Any) -> str:
    """The Tune run of stage `stage` running the configs `names` (all of them described by `spec`).

    One config runs as `<stage>-<name>`, several as `<stage>-stage-<spec_digest(spec)>`, and
    so does every train stage (see `STAGE_RUN_INFIX`): the same configs continue the same run.
    """
    if len(names) == 1 and stage != TRAIN:
        return config_run_name(stage, names[0])
    return stage_run_prefix(stage) + spec_digest(spec)


def config_run_name(stage: str, name: str) -> str:
    """The Tune run of the one config `name` of stage `stage` (self-play, adapt, zero-shot): `<stage>-<name>`."""
    return f"{stage}-{name}"


def marker_path(game_dir: str | Path, stage: str) -> Path:
    """Where stage `stage` of a reproduction's game folder leaves its marker."""
    return Path(game_dir) / f"{stage}{MARKER_SUFFIX}"


def read_marker(marker: Path) -> tuple[float, list[str]]:
    """A stage marker's wall seconds and covered items; (0, []) when there is none.

    Markers from before items were recorded hold only the time, so they cover nothing.
    """
    if not marker.is_file():
        return 0.0, []
    first, *items = marker.read_text().splitlines()
    return float(first.split()[0]), [i for i in items if i]


def write_marker(marker: Path, seconds: float, items: list[str]) -> None:
    """Write a stage marker: `<seconds> s` on the first line, then one covered item per line.

    Whole or not at all (`atomic_files`): a run killed while writing it leaves the marker it
    had, never one that covers only some of its items.
    """
    write_text_atomically(marker, "\n".join([f"{seconds:.1f} s", *items]) + "\n")


def expected_stages(game: str, quick: bool = False) -> tuple[str, ...]:
    """The stages `rllib-conv reproduce` ran for `game`, in order, in a folder whose plan.json predates its `stages`.

    Reproductions now record their stages (the game's record decides: zero-shot where it has
    a new task and the plan zero-shot populations, marginals where it has an oracle); older
    folders hold only the paper's three games, whose fixed plans were: zero-shot on the bandit,
    and on blocks except in the quick plan; no zero-shot nor marginals on Hanabi (no oracle).
    """
    stages = [SELFPLAY, TRAIN, ADAPT]
    if game == "bandit" or (game == "blocks" and not quick):
        stages.append(ZEROSHOT)
    if game in ("bandit", "blocks"):
        stages.append(MARGINALS)
    return tuple(stages)
