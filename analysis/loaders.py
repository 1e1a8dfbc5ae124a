"""Read a reproduction's folders into tidy pandas DataFrames, from files on disk only.

`rllib-conv reproduce GAME --out ROOT` writes `ROOT/<game>/` (its layout is written down
in `rllib_conv.common.run_folders`, which both the writers and this module use). Every loader here takes either such a ROOT (all game
folders under it) or one game folder, never starts Ray or loads a checkpoint, and returns
an empty frame with the documented columns when the files are absent, so a report can
be built from a partial or still-running reproduction.

Identifiers shared by the frames: `game` (plan.json's game, else the folder name),
`population` and `label` (from the experiment name `<population>__<label>`, where label
is the variant's label, `rllib_conv.common.methods.LABELS` for the shipped plans, such as
`modular-lam0.5`, `agg`, `scratch`), `run` (a trained ego's trial folder), `trial` (its folder name).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Iterable

import pandas as pd

from rllib_conv.common import methods
from rllib_conv.common.resources import user_study_csv
from rllib_conv.common.run_folders import (
    ADAPTATION_DIR,
    CROSSPLAY_DIR,
    EVAL_FILE,
    EVALUATION_DIR,
    EXPERIMENT_SEPARATOR,
    GAME_MARKERS,
    HELDOUT_FILE,
    MARGINALS_FILE,
    MARGINALS_FILE_COLUMNS,
    MARKER_SUFFIX,
    PLAN_FILE,
    POPULATIONS_DIR,
    RUNS_DIR,
    SELFPLAY_REPORT_FILE,
    STAGE_PREFIXES,
    STAGES,
    ZEROSHOT_DIR,
    expected_stages,
    experiment_of,
    marker_path,
    read_marker,
    read_trial_config,
    split_experiment,
    trial_folders,
    trial_name,
)
from rllib_conv.common.user_study_table import load_user_study

# Columns that may hold the environment-step counter, in order of preference (ours, new RLlib API, old Tune).
STEP_COLUMNS: tuple[str, ...] = ("env_steps", "num_env_steps_sampled_lifetime", "timesteps_total")
# Highest score of the paper's games (1 coordinated pull; 2 blocks x 10 points; 5 Hanabi cards), for
# folders written before plan.json carried the game's own (`max_score`).
MAX_SCORE: dict[str, float] = {"bandit": 1.0, "blocks": 20.0, "hanabi": 5.0}


def _is_game_dir(path: Path) -> bool:
    return path.is_dir() and (any((path / m).exists() for m in GAME_MARKERS) or any(path.glob(f"*{MARKER_SUFFIX}")))


def game_dirs(root: str | Path) -> list[Path]:
    """The game folders under `root` (or `[root]` when `root` is itself a game folder), sorted by name."""
    root = Path(root)
    if _is_game_dir(root):
        return [root]
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir() if _is_game_dir(p))


def read_plan(game_dir: str | Path) -> dict[str, Any]:
    """plan.json of a game folder ({"game", "seeds", "quick"}); with no file, {"game": <folder name>}."""
    game_dir = Path(game_dir)
    path = game_dir / PLAN_FILE
    plan = json.loads(path.read_text()) if path.is_file() else {}
    plan.setdefault("game", game_dir.name)
    return plan


def max_score(plan: dict[str, Any]) -> float:
    """The best score an episode of `plan`'s game can reach: plan.json's `report.max_score`, which the run
    wrote from the game's record; older folders: `MAX_SCORE`; nan if neither knows the game."""
    value = plan.get("report", {}).get("max_score")
    value = MAX_SCORE.get(str(plan.get("game"))) if value is None else value
    return float("nan") if value is None else float(value)


def game_of(game_dir: str | Path) -> str:
    """The game a folder holds (plan.json's `game`, else the folder name)."""
    return str(read_plan(game_dir)["game"])


def _empty(columns: Iterable[str]) -> pd.DataFrame:
    return pd.DataFrame(columns=list(columns))


def _concat(frames: list[pd.DataFrame], columns: Iterable[str]) -> pd.DataFrame:
    frames = [f for f in frames if not f.empty]
    return pd.concat(frames, ignore_index=True) if frames else _empty(columns)


# --- stage markers -----------------------------------------------------------------------

STAGE_COLUMNS = ["game", "stage", "expected", "done", "seconds"]


def load_stage_times(root: str | Path) -> pd.DataFrame:
    """One row per (game, stage) of `STAGES`: whether the game's plan has it, whether it is done, and the wall seconds its marker records.

    A stage is done when its `<stage>.done` marker exists and covers every item the plan lists
    for it (plan.json's `items`; a marker left by an earlier, smaller plan of the folder does
    not count). The seconds add up every run of the stage on the folder.
    """
    rows = []
    for game_dir in game_dirs(root):
        plan = read_plan(game_dir)
        game = str(plan["game"])
        # Reproductions record their stages in plan.json; older ones ran the fixed plans of their game.
        expected = plan.get("stages") or expected_stages(game, bool(plan.get("quick", False)))
        items = plan.get("items", {})
        for stage in STAGES:
            marker = marker_path(game_dir, stage)
            try:
                seconds, covered = read_marker(marker) if marker.is_file() else (float("nan"), [])
            except ValueError:  # not a marker this code wrote ("<seconds> s", then items)
                seconds, covered = float("nan"), []
            done = marker.is_file() and set(items.get(stage, [])) <= set(covered)
            rows.append(
                {
                    "game": game,
                    "stage": stage,
                    "expected": stage in expected or marker.is_file(),
                    "done": done,
                    "seconds": seconds,
                }
            )
    return pd.DataFrame(rows, columns=STAGE_COLUMNS)


# --- trained egos ------------------------------------------------------------------------

TRIAL_COLUMNS = ["game", "experiment", "population", "label", "trial", "run", "method", "lam", "z_dim", "seed", "env"]


def trial_dirs(game_dir: str | Path) -> list[Path]:
    """The trained-ego folders of a game folder: `runs/<population>__<label>/<trial>/seed=<s>/` (older runs:
    `<trial>/`) holding a config.yaml."""
    runs = Path(game_dir) / RUNS_DIR
    if not runs.is_dir():
        return []
    return sorted(
        t
        for exp in runs.iterdir()
        if exp.is_dir() and EXPERIMENT_SEPARATOR in exp.name and not exp.name.startswith(STAGE_PREFIXES)
        for t in _egos_in(exp)
    )


def _egos_in(experiment: Path) -> list[Path]:
    """The trained-ego folders of one experiment folder (none: an empty list)."""
    try:
        return trial_folders(experiment)
    except ValueError:
        return []


def trial_info(trial: str | Path, game: str | None = None) -> dict[str, Any]:
    """The identifiers of one trial folder (see `TRIAL_COLUMNS`), read from its path and config.yaml."""
    trial = Path(trial)
    cfg = read_trial_config(trial)
    experiment = experiment_of(trial).name
    population, label = split_experiment(experiment)
    if not label:  # not a reproduce experiment (`<population>__<label>`): a sweep's trial names its population itself
        population = str(cfg.get("population", population))
    model = cfg.get("model") or {}
    return {
        "game": game or cfg.get("env", ""),
        "experiment": experiment,
        "population": population,
        "label": label,
        "trial": trial_name(trial),
        "run": str(trial),
        "method": cfg.get("method"),
        "lam": float(cfg.get("lam", 0.0) or 0.0),
        # z_dim null means z is the task module's last hidden layer (the paper's default).
        "z_dim": model.get("z_dim") or model.get("hidden"),
        "seed": cfg.get("seed"),
        "env": cfg.get("env"),
    }


def _read_progress(trial: Path) -> pd.DataFrame:
    """Tune's progress.csv of a trial, or its result.json (one JSON object a line) when the CSV is absent or empty."""
    csv = trial / "progress.csv"
    if csv.is_file() and csv.stat().st_size > 0:
        try:
            # on_bad_lines: a running trial may be caught mid-write; a torn last line is dropped.
            return pd.read_csv(csv, on_bad_lines="skip")
        except (pd.errors.EmptyDataError, pd.errors.ParserError):
            pass
    results = trial / "result.json"
    if results.is_file():
        rows = []
        for line in results.read_text().splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue  # a torn last line of a running trial
            row.pop("config", None)  # the trial's whole config, repeated on every line
            rows.append(row)
        return pd.DataFrame(rows)
    return pd.DataFrame()


def load_training(root: str | Path) -> pd.DataFrame:
    """Training curves: one row per trained-ego trial and training iteration.

    Columns: `TRIAL_COLUMNS`, `training_iteration`, `steps` (environment steps sampled so
    far, from the first of `STEP_COLUMNS` present) and every metric column of the trial's
    progress.csv (for ours: return_mean, return/<partner>, marginal_reg, time_total_s ...).
    A trial restored after an interruption logs some iterations twice; the last log wins.
    """
    frames = [_trial_curve(trial, game_of(game_dir)) for game_dir in game_dirs(root) for trial in trial_dirs(game_dir)]
    return _concat(frames, [*TRIAL_COLUMNS, "steps", "training_iteration"])


def load_sweep(experiment: str | Path) -> pd.DataFrame:
    """Training curves of one `rllib-conv sweep` (or `train`) experiment folder, `STORAGE/NAME`.

    One row per trial and iteration, with the columns of `load_training`; the swept values
    (population, method, lam, seed, z_dim) come from each trial's config.yaml. ValueError
    if the folder holds no trial.
    """
    trials = _egos_in(Path(experiment))
    if not trials:
        raise ValueError(
            f"{str(experiment)!r} holds no trained-ego trial (no */config.yaml); expected a sweep's STORAGE/NAME folder"
        )
    return load_trial_curves(trials)


def load_trial_curves(trials: Iterable[str | Path]) -> pd.DataFrame:
    """Training curves of the given trial folders, one row per trial and iteration, with the columns of `load_training`."""
    return _concat([_trial_curve(Path(t)) for t in trials], [*TRIAL_COLUMNS, "steps", "training_iteration"])


# The columns of `load_trial_summaries` that hold a trial's config (the rest: what it logged and measured).
CONFIG_PREFIX = "config/"


def _flatten(config: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """A nested config as one level of dotted keys (`ppo.lr`); lists become their text, so that they compare."""
    out: dict[str, Any] = {}
    for key, value in config.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict) and value:
            out.update(_flatten(value, f"{name}."))
        else:
            out[name] = str(value) if isinstance(value, (list, dict)) else value
    return out


def load_trial_summaries(trials: Iterable[str | Path]) -> pd.DataFrame:
    """One row per trial folder: `run`; its config.yaml flattened to dotted keys under `CONFIG_PREFIX` (`config/lam`,
    `config/ppo.lr`, ...); the metrics of its last logged iteration (`return_mean`, `env_steps`, ...); and its
    eval.json entries (`eval/marginal_distance/paper`, ...).

    What a sweep's heat map is drawn from; a trial with no log yet has only its config.
    """
    rows = []
    for trial in map(Path, trials):
        row: dict[str, Any] = {"run": str(trial), **{CONFIG_PREFIX + k: v for k, v in _flatten(read_trial_config(trial)).items()}}
        progress = _read_progress(trial)
        if not progress.empty:
            last = progress.sort_values("training_iteration").iloc[-1] if "training_iteration" in progress else progress.iloc[-1]
            row.update(last.to_dict())
        if (trial / EVAL_FILE).is_file():
            try:
                row.update(json.loads((trial / EVAL_FILE).read_text()))
            except json.JSONDecodeError:
                pass  # being written by a running trial
        rows.append(row)
    return pd.DataFrame(rows)


def _trial_curve(trial: Path, game: str | None = None) -> pd.DataFrame:
    """One trial's progress, one row per iteration (the last log of a re-run iteration), with its identifiers."""
    progress = _read_progress(trial)
    if progress.empty or "training_iteration" not in progress.columns:
        return pd.DataFrame()
    progress = progress.drop_duplicates("training_iteration", keep="last").sort_values("training_iteration")
    step_column = next((c for c in STEP_COLUMNS if c in progress.columns), None)
    steps = progress[step_column] if step_column else pd.Series(float("nan"), index=progress.index)
    info = trial_info(trial, game)
    ident = pd.DataFrame({k: [v] * len(progress) for k, v in info.items()}, index=progress.index)
    ident["steps"] = steps
    metrics = progress.drop(columns=[c for c in ident.columns if c in progress.columns])
    return pd.concat([ident, metrics], axis=1).reset_index(drop=True)


EVAL_COLUMNS = [
    *TRIAL_COLUMNS,
    "partner",
    "mean_return",
    "stderr",
    "exact_return",
    "marginal_distance",
    "marginal_distance_all",
    "wall_s",
]


def load_evals(root: str | Path) -> pd.DataFrame:
    """Final evaluation of each trained ego with each training partner (eval.json): one row per trial and partner.

    Columns `EVAL_COLUMNS`; `exact_return` is NaN where the game has no exact expectation,
    the marginal distances (the trial's, repeated on each of its rows) NaN for methods without them.
    """
    rows = []
    for game_dir in game_dirs(root):
        game = game_of(game_dir)
        for trial in trial_dirs(game_dir):
            path = trial / EVAL_FILE
            if not path.is_file():
                continue
            try:
                ev = json.loads(path.read_text())
            except json.JSONDecodeError:
                continue  # being written by a running reproduction
            info = trial_info(trial, game)
            partners = sorted({k.split("/", 2)[2] for k in ev if k.startswith("eval/mean/")})
            for partner in partners:
                rows.append(
                    {
                        **info,
                        "partner": partner,
                        "mean_return": ev.get(f"eval/mean/{partner}"),
                        "stderr": ev.get(f"eval/stderr/{partner}"),
                        "exact_return": ev.get(f"eval/exact/{partner}", float("nan")),
                        "marginal_distance": ev.get("eval/marginal_distance/paper", float("nan")),
                        "marginal_distance_all": ev.get("eval/marginal_distance/all", float("nan")),
                        "wall_s": ev.get("wall_s", float("nan")),
                    }
                )
    return pd.DataFrame(rows, columns=EVAL_COLUMNS)


# --- stage tables ------------------------------------------------------------------------


def read_stage_csv(path: str | Path, game: str = "") -> pd.DataFrame:
    """One adaptation or zero-shot CSV (`<name>.csv`) with the identifiers the loaders add: game, population, label, trial, experiment.

    A reproduction names its CSVs `<population>__<label>`; any other name is the population,
    and each row's label comes from its method (`<method>-lam<lam>` for a regularised
    method with lam > 0, as reproduce names them; the method's name otherwise). `exact_return` is added (NaN) where the file has none.
    """
    path = Path(path)
    table = pd.read_csv(path)
    population, label = split_experiment(path.stem)
    labels = (
        [label] * len(table)
        if label
        else [methods.row_label(m, lam) for m, lam in zip(table["method"], table.get("lam", [0.0] * len(table)))]
    )
    table.insert(0, "label", labels)
    table.insert(0, "population", population)
    table.insert(0, "game", game)
    # The run paths are absolute on the machine that ran them; the trial folder name is portable.
    table["trial"] = [trial_name(str(r)) for r in table["run"]]
    table["experiment"] = [experiment_of(str(r)).name for r in table["run"]]
    if "exact_return" not in table.columns:
        table["exact_return"] = float("nan")
    return table


def _read_tables(root: str | Path, folder: str) -> list[pd.DataFrame]:
    """Every `<game>/<folder>/<population>__<label>.csv`, with game, population, label, experiment, trial columns added."""
    frames = []
    for game_dir in game_dirs(root):
        game = game_of(game_dir)
        for path in sorted((game_dir / folder).glob("*.csv")):
            table = read_stage_csv(path, game)
            if not table.empty:
                frames.append(table)
    return frames


ADAPT_COLUMNS = [
    "game",
    "population",
    "label",
    "run",
    "method",
    "lam",
    "z_dim",
    "seed",
    "partner",
    "steps",
    "mean_return",
    "stderr",
    "exact_return",
    "trial",
    "experiment",
]


def load_adaptation(root: str | Path) -> pd.DataFrame:
    """Adaptation curves: one row per (trained ego run, test partner, adaptation step count) from `adaptation/*.csv`.

    Columns `ADAPT_COLUMNS`. For `scratch`, `run` is the modular ego whose seed it shares
    (a fresh network is trained; nothing is loaded from that run).
    """
    return _concat(_read_tables(root, ADAPTATION_DIR), ADAPT_COLUMNS)


ZEROSHOT_COLUMNS = [
    "game",
    "population",
    "label",
    "run",
    "method",
    "lam",
    "seed",
    "partner",
    "mean_return",
    "stderr",
    "exact_return",
    "trial",
    "experiment",
]


def load_zeroshot(root: str | Path) -> pd.DataFrame:
    """Zero-shot results on the new task: one row per (trained ego run, test partner) from `zeroshot/*.csv`. Columns `ZEROSHOT_COLUMNS`."""
    return _concat(_read_tables(root, ZEROSHOT_DIR), ZEROSHOT_COLUMNS)


# The file's columns, with the game, population and label first and what the loader adds last.
MARGINAL_COLUMNS = [
    "game",
    "population",
    "label",
    *(c for c in MARGINALS_FILE_COLUMNS if c != "population"),
    "experiment",
    "trial",
]


def load_marginals(root: str | Path) -> pd.DataFrame:
    """Task-module distances to the true marginals: one row per trained ego (marginals.csv). Columns `MARGINAL_COLUMNS`.

    `distance` averages over the states the paper's figure uses (more than one optimal
    action), `distance_all_states` over every state.
    """
    frames = []
    for game_dir in game_dirs(root):
        path = game_dir / MARGINALS_FILE
        if not path.is_file():
            continue
        table = pd.read_csv(path)
        if table.empty:
            continue
        table.insert(0, "game", game_of(game_dir))
        table["experiment"] = [
            experiment_of(str(r)).name for r in table["run"]
        ]  # from the path: replica folders sit a level deeper
        table["population"] = [split_experiment(e)[0] for e in table["experiment"]]
        table["label"] = [split_experiment(e)[1] for e in table["experiment"]]
        table["trial"] = [trial_name(str(r)) for r in table["run"]]
        frames.append(table)
    out = _concat(frames, MARGINAL_COLUMNS)
    return out[[c for c in MARGINAL_COLUMNS if c in out.columns] + [c for c in out.columns if c not in MARGINAL_COLUMNS]]


SELFPLAY_COLUMNS = [
    "game",
    "population",
    "partner",
    "split",
    "pair",
    "seed",
    "passed",
    "score",
    "steps_to_gate",
    "env_steps",
    "wall_s",
]


def load_selfplay_reports(root: str | Path) -> pd.DataFrame:
    """Self-play population reports: one row per trained pair (`populations/<name>/selfplay_report.csv`). Columns `SELFPLAY_COLUMNS`."""
    frames = []
    for game_dir in game_dirs(root):
        for path in sorted((game_dir / POPULATIONS_DIR).glob(f"*/{SELFPLAY_REPORT_FILE}")):
            table = pd.read_csv(path)
            table.insert(0, "population", path.parent.name)
            table.insert(0, "game", game_of(game_dir))
            table["passed"] = table["passed"].astype(str).str.lower().isin(["true", "1"])
            frames.append(table)
    return _concat(frames, SELFPLAY_COLUMNS)


HELDOUT_COLUMNS = ["game", "agent", "seed", "player", "partner", "episodes", "mean_return", "stderr"]
# Per method, as `rllib-conv evaluate` writes them in summary.json's `aggregates`.
EVALUATION_AGGREGATES = ["seeds", "partners", "mean", "mean_low", "mean_high", "iqm", "iqm_low", "iqm_high", "return"]
EVALUATION_COLUMNS = ["game", "population", "set", "role", "label", *EVALUATION_AGGREGATES, "bounds"]


def load_evaluations(root: str | Path) -> pd.DataFrame:
    """The field's protocol stage (`<game>/evaluation/<population>__<role>/summary.json`, written by `rllib-conv
    evaluate`): one row per (game, population, set, method) with its aggregates. Columns `EVALUATION_COLUMNS`;
    `bounds` says whether the set's bounds are exact or declared (trained best responses)."""
    rows = []
    for game_dir in game_dirs(root):
        for summary in sorted((game_dir / EVALUATION_DIR).glob("*/summary.json")):
            record = json.loads(summary.read_text())
            population, role = split_experiment(summary.parent.name)
            declared = bool(record["eval_set"].get("bounds"))
            for agg in record["aggregates"]:
                rows.append(
                    {
                        "game": game_of(game_dir),
                        "population": population,
                        "set": record["eval_set"]["name"],
                        "role": role,
                        "label": split_experiment(agg["agent"])[1],
                        **{k: agg[k] for k in EVALUATION_AGGREGATES},
                        "bounds": "declared" if declared else "exact",
                    }
                )
    table = pd.DataFrame(rows, columns=EVALUATION_COLUMNS)
    # One seed has no interval: summary.json holds null, the tables NaN.
    return table.astype({k: float for k in EVALUATION_AGGREGATES if k not in ("seeds", "partners")})


def load_heldout(root: str | Path) -> pd.DataFrame:
    """The held-out evaluations (`<game>/heldout.csv`): one row per (game, agent, seed, partner). Columns `HELDOUT_COLUMNS`."""
    frames = []
    for game_dir in game_dirs(root):
        if (game_dir / HELDOUT_FILE).is_file():
            table = pd.read_csv(game_dir / HELDOUT_FILE)
            table.insert(0, "game", game_of(game_dir))
            frames.append(table)
    return _concat(frames, HELDOUT_COLUMNS)


def load_crossplay(root: str | Path) -> dict[str, pd.DataFrame]:
    """Cross-play matrices (CSVs of `rllib-conv crossplay`) found in `crossplay/` folders.

    Looks in `ROOT/crossplay/` and `<game>/crossplay/`; returns {file stem: square
    matrix}, rows = population A's members in the ego seat, columns = B's members.
    """
    root = Path(root)
    folders = [root / CROSSPLAY_DIR, *(g / CROSSPLAY_DIR for g in game_dirs(root) if g != root)]
    out: dict[str, pd.DataFrame] = {}
    for folder in folders:
        for path in sorted(folder.glob("*.csv")):
            matrix = pd.read_csv(path, index_col=0)
            if not matrix.empty:
                out[path.stem] = matrix
    return out


# --- user study --------------------------------------------------------------------------


def user_study_files(paths: str | Path | Iterable[str | Path] | None = None) -> list[Path]:
    """The user-study CSVs named by `paths` (files, or folders whose *.csv are taken); None gives the paper's table."""
    if paths is None:
        return [user_study_csv()]
    if isinstance(paths, (str, Path)):
        paths = [paths]
    files: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            files += sorted(p.glob("*.csv"))
        elif p.is_file():
            files.append(p)
        else:
            raise FileNotFoundError(f"user-study CSV or folder {str(p)!r} does not exist")
    return files


def load_user_study_csvs(paths: str | Path | Iterable[str | Path] | None = None) -> pd.DataFrame:
    """Read and concatenate user-study CSVs (the paper's table and/or recorded live sessions).

    Each file is validated by `rllib_conv.common.user_study_table.load_user_study` (one row per
    pair, task, context and try; `coordinated` = the try won the prize). Added columns:
    `source` (the file name) and `pair_id` ("<source>:<pair>"), because live sessions
    recorded in separate files may reuse pair numbers.
    """
    frames = []
    for path in user_study_files(paths):
        df = load_user_study(path)
        df["source"] = path.name
        df["pair_id"] = [f"{path.name}:{p}" for p in df["pair"]]
        frames.append(df)
    if not frames:
        return _empty(
            ["pair", "task", "context", "try", "action_1", "action_2", "arm_1", "arm_2", "coordinated", "source", "pair_id"]
        )
    return pd.concat(frames, ignore_index=True)
