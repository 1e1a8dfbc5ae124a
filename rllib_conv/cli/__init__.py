"""`rllib-conv`: the command line. Each subcommand checks its arguments, calls one pipeline and says where its results went.

Bad input (an out-of-range option, an unknown env, population or config key, a missing or
malformed file) prints one `rllib-conv: error: ...` line naming the argument or file and
exits with status 2, before anything is written. Arguments and files are checked with
light imports (pydantic, YAML, the env registry; no torch, no Ray), so `--help` and such
errors answer at once; a pipeline loads only when there is work to do. Ray's and Tune's
own messages are hidden unless `-v` is given. Every command that writes ends with one line
saying where: `wrote <path>` or `results in <folder>`.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import hashlib
import importlib.util
import json
import logging
import os
import re
import sys
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator, NoReturn, Sequence

import yaml

from rllib_conv.common.tracking import DEFAULT_LOGGERS, LOGGERS

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
MAX_PORT = 65535
MAX_NAME = 120  # longer derived output names are cut and keep a digest, so they stay unique and fit a file system

# What `-v` would show: Tune's experiment box and its TensorBoard hint into Ray's temporary
# folder (our own lines say where results go), Ray's token-auth and deprecation warnings
# (driver and workers), Python warnings in the workers Ray starts.
QUIET_ENV = {"RAY_AIR_NEW_OUTPUT": "0", "RAY_LOGGER_LEVEL": "error", "PYTHONWARNINGS": "ignore"}

# The `--set` keys of adapt and zeroshot that no option sets (the others are options).
ADAPT_SET_KEYS = {
    "every": "env steps between evaluations, one PPO update each (bandit 16, blocks and Hanabi 640)",
    "steps": "env steps of adaptation (bandit 240, blocks and Hanabi 25600)",
    "episodes": "episodes per evaluation (200)",
    "ppo": "PPO settings replacing the run's, e.g. --set ppo.lr=1e-4 or ppo.num_epochs=10",
    "seed": "seed of the evaluation episodes (0)",
    "max_pack": "curves trained together in one algorithm, for speed (32; each trains as it would alone)",
    "posterior": "--head-init posterior's priors, e.g. --set posterior.recombined=0.5 posterior.novel=0.1 posterior.epsilon=0.05 posterior.handover=0.95",
    "guard_z": "--guard's margin: standard errors by which the adapting ego's mean return must beat the prior's (0.5)",
}
ZEROSHOT_SET_KEYS = {
    "head_steps": "step 1: env steps training the test partners' heads on the old task (bandit 2560, blocks 300000)",
    "task_steps": "step 2: env steps re-training the task module on the new task (bandit 10000, blocks 400000)",
    "head_lam": "step 1: regulariser weight (default: the run's lam)",
    "task_lam": "step 2: regulariser weight (default: the run's lam)",
    "task_entropy": "step 2: entropy bonus, a constant or a schedule [[0, 0.05], [STEP, VALUE]] (0.05)",
    "task_z_lr_scale": "step 2: learning-rate scale of the z layers (1; 0 freezes them)",
    "reset_task_logits": "step 2: re-initialise the task logits layer first (true)",
    "episodes": "step 3: evaluation episodes (200)",
    "seed": "seed of the evaluation episodes (0)",
    "max_pack": "egos run together in one algorithm, for speed (32; each runs as it would alone)",
}

SEAT_SYNTAX = """\
A seat is SOURCE:WHAT, read in this order:
  KIND:PARAMS   a scripted partner kind with its parameters as a YAML mapping,
                e.g. 'bandit_convention:{arms: [0, 5, 2, 3]}' (kinds and parameters: docs/cli.md)
  RUN:MODULE    a module of a trained ego's last checkpoint: RUN:ego@NAME (the head trained with
                partner NAME), RUN:ego (the one head of agg/maml egos), RUN:task (the task module alone)
  POP:NAME      member NAME of population POP (a built-in name, a manifest or a population folder)
Seats fill the game's agents in order (player_0, player_1, ...).
"""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one `rllib-conv: error:` line and exit 2, like every other bad input."""

    def error(self, message: str) -> NoReturn:
        sys.stderr.write(f"rllib-conv: error: {self.prog}: {message} (see {self.prog} --help)\n")
        sys.exit(EXIT_USAGE)


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}")
    return value


def _one_line(exc: BaseException) -> str:
    """The exception's message on one line (pydantic errors as `key: problem` clauses)."""
    from pydantic import ValidationError

    if isinstance(exc, ValidationError):
        from rllib_conv.common.config_files import describe

        return describe(exc)
    return " ".join(str(exc).split())


@contextlib.contextmanager
def _quiet(verbose: bool, keep_logs: bool = False) -> Iterator[None]:
    """Hide Ray's, Tune's and Python's warnings while a command runs, unless `verbose`.

    The environment variables reach the Ray processes the command starts (a user's own
    settings win); Python warnings and log records up to WARNING are dropped in this
    process (Ray resets its loggers' levels when imported, so levels alone would not do),
    except with `keep_logs` (the web app's own warnings matter). Everything is restored
    afterwards, so calling `main` from Python leaves the process as it was.
    """
    if verbose:
        yield
        return
    added = {k: v for k, v in QUIET_ENV.items() if k not in os.environ}
    os.environ.update(added)
    if not keep_logs:
        logging.disable(logging.WARNING)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logging.disable(logging.NOTSET)
        for key in added:
            os.environ.pop(key, None)


# --- checking configs and arguments, with light imports ------------------------------------


def _yaml_value(text: str, what: str) -> Any:
    """`text` parsed as YAML; ValueError naming `what` when it is not valid YAML."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{what}: not valid YAML ({_one_line(exc)})") from None


def _blame(error: dict[str, Any], origins: dict[tuple[str, ...], str], default: str) -> tuple[str, str]:
    """One pydantic problem as (the argument that set its key, `key: problem`)."""
    loc = tuple(str(p) for p in error["loc"])
    msg = error["msg"].removeprefix("Value error, ")
    for key, origin in origins.items():
        n = min(len(key), len(loc))
        if loc and loc[:n] == key[:n]:
            return origin, msg if loc == key and not origin.startswith("--set") else f"{'.'.join(loc)}: {msg}"
    if not loc and origins:  # a check across keys: the file (or arguments) together with the options
        return f"{default} with {', '.join(origins.values())}", msg
    return default, f"{'.'.join(loc)}: {msg}" if loc else msg


def _blamed(errors: list[dict[str, Any]], origins: dict[tuple[str, ...], str], default: str) -> str:
    """Every problem, grouped by the argument it is blamed on: `--set a=1: a: ...; file.yaml: b: ...; c: ...`."""
    grouped: dict[str, list[str]] = {}
    for error in errors:
        origin, clause = _blame(error, origins, default)
        grouped.setdefault(origin, []).append(clause)
    return "; ".join(f"{origin}: {'; '.join(clauses)}" for origin, clauses in grouped.items())


def _validated(raw: Any, schema: type, origins: dict[tuple[str, ...], str], default: str) -> list[Any]:
    """Every grid combination of `raw`, validated against `schema`; each problem blamed on the argument that set its key.

    `origins` maps key paths to the options that set them (`--pick-steps`, `--set lam=0.3`);
    other keys are blamed on `default` (the YAML file, or "arguments").
    """
    from pydantic import ValidationError

    from rllib_conv.common.config_files import expand_grid

    if not isinstance(raw, dict):
        raise ValueError(f"{default}: expected a mapping of settings, got {type(raw).__name__}")
    variants = []
    for variant in expand_grid(raw):
        try:
            variants.append(schema.model_validate(variant))
        except ValidationError as exc:
            given = {key: origin for key, origin in origins.items() if _has_path(variant, key)}  # options left unset take no blame
            raise ValueError(_blamed(exc.errors(), given, default)) from None
    return variants


def _has_path(raw: Any, key: tuple[str, ...]) -> bool:
    """Whether the nested mapping `raw` has a value at `key`."""
    for part in key:
        if not isinstance(raw, dict) or part not in raw:
            return False
        raw = raw[part]
    return True


def _with_sets(raw: dict[str, Any], sets: Sequence[str], schema: type, origins: dict[tuple[str, ...], str], default: str) -> tuple[dict, list]:
    """`raw` with the `--set KEY=VALUE` overrides applied, and its validated grid combinations."""
    from rllib_conv.common.config_files import parse_override, set_path

    raw, origins = copy.deepcopy(raw), dict(origins)
    for text in sets:
        try:
            key, value = parse_override(text)
        except yaml.YAMLError as exc:
            raise ValueError(f"--set {text}: not valid YAML ({_one_line(exc)})") from None
        try:
            set_path(raw, key, value)
        except (AttributeError, TypeError):  # a key below a value that is not a mapping (lam.x=1)
            raise ValueError(f"--set {text}: {'.'.join(key[:-1])} is not a section of settings") from None
        origins[key] = f"--set {text}"
    return raw, _validated(raw, schema, origins, default)


def _load_config(path: str | Path, sets: Sequence[str], schema: type) -> tuple[dict, list]:
    """A config YAML with its `--set` overrides, validated (every grid combination); problems name the file or the `--set`."""
    from rllib_conv.common.config_files import read_yaml

    if Path(path).is_dir():
        raise ValueError(f"config file {str(path)!r} is a folder; expected a YAML file")
    raw = read_yaml(path)
    return _with_sets({} if raw is None else raw, sets, schema, {}, str(path))


def _check_trial(trial: Path) -> None:
    """A trial folder's config.yaml parses and validates, and it has a checkpoint (the pipeline verifies its files)."""
    from pydantic import ValidationError

    from rllib_conv.common.config_files import describe, read_yaml
    from rllib_conv.common.run_folders import CONFIG_FILE, checkpoints
    from rllib_conv.training.experiment import ExperimentConfig

    path = trial / CONFIG_FILE
    try:
        ExperimentConfig.model_validate(read_yaml(path, "trial config") or {})
    except ValidationError as exc:
        raise ValueError(f"trial config {str(path)!r}: {describe(exc)}") from None
    if not checkpoints(trial):
        raise ValueError(f"trial {str(trial)!r} has no checkpoint (checkpoint_* folders)")


def _trials(runs: Sequence[str]) -> list[Path]:
    """Every trained-ego trial folder of the RUNS arguments, each checked (`_check_trial`)."""
    from rllib_conv.common.run_folders import trial_folders

    trials = [t for run in runs for t in trial_folders(run)]
    for trial in trials:
        _check_trial(trial)
    return trials


# --- naming outputs after their inputs and saying where they went --------------------------


def _digest(texts: Sequence[str]) -> str:
    return hashlib.sha1("\n".join(texts).encode()).hexdigest()[:6]


def _slug(text: str) -> str:
    """`text` as a folder and file name: runs of characters outside [A-Za-z0-9._=+@,-] become one `_`; long names keep a digest."""
    slug = re.sub(r"[^\w.=+@,-]+", "_", text).strip("_")
    return slug if len(slug) <= MAX_NAME else f"{slug[: MAX_NAME - 7]}-{_digest([text])}"


def _trial_id(trial: Path) -> str:
    """Tune's short id of a trial folder `<Trainable>_<id>_<index>_...` (`6b1e2_00000`); the folder name otherwise."""
    parts = trial.name.split("_")
    return "_".join(parts[1:3]) if len(parts) >= 3 else trial.name


def _run_label(run: str | Path) -> str:
    """A short name of a RUNS argument: its experiment's name, then the Tune trial id and sub-folders below it.

    `runs/tiny` -> `tiny`; `runs/tiny/EgoTrainable_6b1e2_00000_0_...` -> `tiny-6b1e2_00000`; a
    folder inside a trial (one trained ego of several) adds its own name. A folder outside any
    experiment (no experiment.yaml above it) is named by its parent and itself.
    """
    from rllib_conv.common.run_folders import SPEC_FILE

    path = Path(run).resolve()
    experiment = next((p for p in (path, *path.parents) if (p / SPEC_FILE).is_file()), path.parent)
    below = path.relative_to(experiment).parts if path != experiment else ()
    return "-".join([experiment.name, *(_trial_id(Path(part)) for part in below)])


def _name_from(runs: Sequence[str], extras: Sequence[str]) -> str:
    """An output name after the inputs: the runs (the first, a count and a digest when several), then the options that differ."""
    labels = [_run_label(r) for r in runs]
    head = labels[0] if len(labels) == 1 else f"{labels[0]}+{len(labels) - 1}-more-{_digest(sorted(str(Path(r).resolve()) for r in runs))}"
    return _slug("-".join([head, *extras]))


def _note_reuse(folder: Path, spec: dict[str, Any], egos: int | None = None) -> None:
    """Say so when `folder` already holds this very experiment: Tune continues it instead of starting over."""
    from rllib_conv.common.run_folders import EVAL_FILE, SPEC_FILE, trial_folders

    path = folder / SPEC_FILE
    if not path.is_file() or yaml.safe_load(path.read_text()) != spec:
        return  # nothing there, or another experiment (the pipeline refuses that one)
    done = ""
    if egos:
        try:
            finished = sum((t / EVAL_FILE).is_file() for t in trial_folders(folder))
        except ValueError:  # no trained ego written yet
            finished = 0
        done = f" ({finished} of {egos} trained egos finished)"
    print(f"note: {folder} already holds this experiment{done}: finished trials are kept, not run again, and unfinished ones continue; delete the folder to start over")


def _plot_folder() -> Callable[[Path], list[Path]] | None:
    """`analysis.plots.plot_folder`, or None in an installation without it."""
    if importlib.util.find_spec("analysis") is None or importlib.util.find_spec("analysis.plots") is None:
        return None
    from analysis.plots import plot_folder

    return plot_folder


def _figures(path: Path) -> list[Path]:
    """Draw the figures of a finished command's results (a folder or a CSV); a drawing problem is a warning, never a lost result."""
    plot_folder = _plot_folder()
    if plot_folder is None:
        return []
    try:
        return list(plot_folder(path))
    except Exception as exc:  # the results are written; a figure is not worth failing the command
        print(f"rllib-conv: warning: no figures for {path}: {_one_line(exc)} (`rllib-conv plot {path}` retries)", file=sys.stderr)
        return []


def _wrote_with_figures(csv: Path) -> None:
    """Draw a stage CSV's figure, then say where both went (the CSV last)."""
    for figure in _figures(csv):
        print(f"figure: {figure}")
    print(f"wrote {csv}")


def _table(frame: Any, width: int = 160) -> str:
    import pandas as pd

    with pd.option_context("display.width", width, "display.max_colwidth", 60, "display.float_format", "{:.3f}".format):
        return frame.to_string(index=False)


# --- the commands ---------------------------------------------------------------------------


def _cmd_envs(args: argparse.Namespace) -> None:
    from rllib_conv import envs

    for name in envs.names():
        print(name)


def _cmd_partners_list(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv import partners

    rows = []
    for name in partners.names():
        pop = partners.get(name)
        rows.append(
            {
                "population": name,
                "env": pop.env,
                "env_config": pop.env_config,
                "train": len(pop.entries("train")),
                "test": len(pop.entries("test")),
                "description": pop.description,
            }
        )
    with pd.option_context("display.max_colwidth", 70, "display.width", 200):
        print(pd.DataFrame(rows).to_string(index=False))
    print("\nthe members of one (their names for --partner, kinds, params): rllib-conv partners show NAME")


def _cmd_partners_show(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv import partners

    pop = partners.get(args.population)
    print(f"{pop.name}: {pop.env} {pop.env_config}, partners in seat {pop.partner_agent}")
    if pop.description:
        print(pop.description)
    rows = [{"partner": e.name, "split": e.split, "kind": e.kind, "params": json.dumps(e.params)} for e in pop.partners]
    with pd.option_context("display.max_colwidth", 100, "display.width", 200):
        print(pd.DataFrame(rows).to_string(index=False))


def _cmd_demo(args: argparse.Namespace) -> None:
    from rllib_conv.common.resources import config_file
    from rllib_conv.training.experiment import ExperimentConfig

    raw, _ = _load_config(config_file("bandit_modular.yaml"), ["name=demo", *args.set], ExperimentConfig)  # the demo's config
    _note_reuse(Path(args.storage) / "demo", raw, egos=1)
    from rllib_conv.pipelines.demo import demo

    demo(storage=args.storage, address=args.address, overrides=args.set)
    print(f"results in {Path(args.storage) / 'demo'}")


def _cmd_train(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv.common.run_folders import SPEC_FILE
    from rllib_conv.training.experiment import ExperimentConfig

    raw, variants = _load_config(args.config, args.set, ExperimentConfig)
    folder = Path(args.storage) / variants[0].name
    sweep = args.command == "sweep"
    if sweep and args.resume and not (folder / SPEC_FILE).is_file():
        raise ValueError(f"--resume: {str(folder)!r} holds no sweep to resume (run without --resume to start it)")
    _note_reuse(folder, raw, egos=len(variants))
    from rllib_conv.pipelines.train import run

    results = run(raw, storage=args.storage, address=args.address, progress="table" if sweep else "lines", resume=sweep and args.resume, loggers=args.log)
    rows = []
    for r in results:
        m = r.metrics or {}
        cfg = r.config or {}  # the trial's values; unset ones are the schema's defaults
        row = {"trial": _trial_id(Path(r.path))}
        row |= {k: cfg.get(k, ExperimentConfig.model_fields[k].default) for k in ("population", "method", "lam", "seed")}
        row |= {"env_steps": m.get("env_steps"), "return": m.get("return_mean"), "marginal_L1": m.get("eval/marginal_distance/paper")}
        rows.append({**row, "error": "yes" if r.error else ""})
    print(_table(pd.DataFrame(rows)))
    if results.errors:
        raise RuntimeError(f"{len(results.errors)} trial(s) failed; see the error.txt files under {folder}")
    for figure in _figures(folder):
        print(f"figure: {figure}")
    print(f"TensorBoard: tensorboard --logdir {folder}")
    print(f"results in {folder}")


def _cmd_partners_train(args: argparse.Namespace) -> None:
    from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

    raw, variants = _load_config(args.config, args.set, SelfPlayConfig)
    target = Path(args.out) / variants[0].name
    if target.exists() and not args.overwrite:
        raise ValueError(f"population folder {str(target)!r} already exists; choose another name or pass --overwrite")
    from rllib_conv.pipelines.selfplay import train_population

    population, report = train_population(raw, out=args.out, storage=args.storage, address=args.address, overwrite=args.overwrite, loggers=args.log)
    print(_table(report))
    failed = report.loc[~report["passed"].astype(bool), "partner"].tolist()
    if failed:
        print(f"not kept (did not reach the gate): {', '.join(failed)}")
    print(f"population {population.name!r}: {len(population.partners)} partners kept")
    print(f"wrote {target}")


def _cmd_crossplay(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv import partners
    from rllib_conv.pipelines.crossplay import crossplay, write_crossplay

    a, b = partners.get(args.a), partners.get(args.b)
    matrix = crossplay(a, b, episodes=args.episodes, seed=args.seed)
    csv, png = write_crossplay(matrix, args.out, f"{a.name}__{b.name}")
    with pd.option_context("display.width", 250, "display.float_format", "{:.2f}".format):
        print(matrix.to_string())
    print(f"wrote {csv} and {png}")


def adapt_summary(curves: Any) -> Any:
    """The adaptation curves as one narrow table: env steps down, per (method, lam) the mean return (and exact, on the bandit)."""
    curves = curves.assign(label=curves["method"].astype(str) + " lam " + curves["lam"].astype(str))
    metrics = [(key, short) for key, short in (("mean_return", "return"), ("exact_return", "exact")) if curves[key].notna().any()]
    table = curves.pivot_table(index="steps", columns="label", values=[key for key, _ in metrics], aggfunc="mean")
    names = dict(metrics)
    table.columns = [f"{label} {names[key]}" for key, label in table.columns]
    order = [f"{label} {short}" for label in sorted(curves["label"].unique()) for _, short in metrics]
    return table[order].reset_index()


def _cmd_adapt(args: argparse.Namespace) -> None:
    from rllib_conv.common.run_folders import ADAPT_PREFIX
    from rllib_conv.pipelines.adapt_config import AdaptConfig

    _trials(args.runs)
    changed = [
        args.method,
        None if args.head_init == "fresh" else args.head_init,
        args.pick_steps and f"pick-steps={args.pick_steps}",
        "frozen-task" if args.frozen_task else None,
        "guarded" if args.guard else None,
        None if args.split == "test" else f"{args.split}-split",
        args.population and Path(args.population).stem,
    ]
    extras = [v for v in changed if v] + list(args.partner or []) + list(args.set)
    name = args.name or _name_from(args.runs, extras)
    raw = {"name": name, "runs": args.runs, "split": args.split, "train_task": not args.frozen_task, "head_init": args.head_init}
    options = {"population": args.population, "partners": args.partner, "method": args.method, "pick_steps": args.pick_steps, "guard": args.guard or None}
    raw.update({k: v for k, v in options.items() if v is not None})
    origins = {("name",): "--name", ("population",): "--population", ("partners",): "--partner", ("pick_steps",): "--pick-steps", ("guard",): "--guard"}
    raw, _ = _with_sets(raw, args.set, AdaptConfig, origins, "arguments")
    _note_reuse(Path(args.storage) / f"{ADAPT_PREFIX}{name}", raw)
    from rllib_conv.pipelines.adapt import run_adaptation

    curves = run_adaptation(raw, out=args.out, storage=args.storage, address=args.address, loggers=args.log)
    print("mean over partners and seeds, by env steps:")
    print(_table(adapt_summary(curves)))
    _wrote_with_figures(Path(args.out) / f"{name}.csv")


def _cmd_zeroshot(args: argparse.Namespace) -> None:
    from rllib_conv.common.run_folders import ZEROSHOT_PREFIX
    from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig

    _trials(args.runs)
    extras = ([Path(args.new_population).stem] if args.new_population else []) + list(args.set)
    name = args.name or _name_from(args.runs, extras)
    raw = {"name": name, "runs": args.runs}
    if args.new_population:
        raw["new_population"] = args.new_population
    raw, _ = _with_sets(raw, args.set, ZeroShotConfig, {("name",): "--name", ("new_population",): "--new-population"}, "arguments")
    _note_reuse(Path(args.storage) / f"{ZEROSHOT_PREFIX}{name}", raw)
    from rllib_conv.pipelines.zeroshot import run_zeroshot

    table = run_zeroshot(raw, out=args.out, storage=args.storage, address=args.address, loggers=args.log)
    print(_table(table.drop(columns=["run"])))
    _wrote_with_figures(Path(args.out) / f"{name}.csv")


def _cmd_marginals(args: argparse.Namespace) -> None:
    trials = _trials(args.runs)
    extras = [f"{k}={v}" for k, v, default in (("episodes", args.episodes, 200), ("seed", args.seed, 0)) if v != default]
    path = Path(args.out) / f"{_slug(args.name) if args.name else _name_from(args.runs, extras)}.csv"
    from rllib_conv.pipelines.marginals import marginal_report

    table = marginal_report(trials, episodes=args.episodes, seed=args.seed)
    if table.empty:
        raise ValueError(f"RUNS {args.runs}: no trained ego there has a learned estimate of the marginals (see the method registry's `marginals`)")
    path.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(path, index=False)
    print(_table(table.drop(columns=["run"])))
    print(f"wrote {path}")


def _cmd_pair(args: argparse.Namespace) -> None:
    from rllib_conv.pipelines.pair_config import PairConfig, is_run, split_seat

    env_config = None if args.env_config is None else _yaml_value(args.env_config, "--env-config")
    raw = {"seats": args.seats, "episodes": args.episodes, "seed": args.seed, "env": args.env, "env_config": env_config}
    origins = {("seats",): "SEATS", ("env",): "--env", ("env_config",): "--env-config", ("episodes",): "--episodes"}
    cfg = _validated(raw, PairConfig, origins, "arguments")[0]
    labels = []
    for seat in cfg.seats:
        source, what = split_seat(seat)
        if is_run(source):
            _trials([source])
        labels.append(f"{_run_label(source) if is_run(source) else Path(source).stem}-{what}")
    path = Path(args.out) / f"{_slug(args.name or '__'.join(labels))}.csv"
    from rllib_conv.pipelines.pair import pair

    table = pair(cfg)
    path.parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(path, index=False)
    print(_table(table.T.reset_index().set_axis(["", "value"], axis=1), width=250))
    print(f"wrote {path}")


def _cmd_play(args: argparse.Namespace) -> None:
    import errno

    if not 0 <= args.port <= MAX_PORT:
        raise ValueError(f"--port: expected a port 0-{MAX_PORT} (0 picks a free one), got {args.port}")
    if args.run is not None and Path(args.run).is_dir():  # the ego's trial folder (its agents and test runs: play checks them)
        _trials([args.run])
    from rllib_conv.play.command import run as play

    try:
        play(args)
    except OSError as exc:
        if exc.errno in (errno.EADDRINUSE, errno.EACCES):
            raise ValueError(f"--port {args.port}: {exc.strerror} (choose another port, or 0 for a free one)") from None
        raise


def _check_report_inputs(root: str | Path, user_study: Sequence[str] | None) -> None:
    """`root` holds a reproduction (one game folder or several) and every `--user-study` path exists."""
    from analysis.loaders import game_dirs

    if not game_dirs(root):
        raise ValueError(
            f"ROOT {str(root)!r} is not a reproduce folder: no game folder (plan.json, runs/, adaptation/, ...) in it or below; "
            "expected a `rllib-conv reproduce --out` folder or one of its game folders"
        )
    for path in user_study or []:
        if not Path(path).exists():
            raise ValueError(f"--user-study {str(path)!r} does not exist")


def _cmd_reproduce(args: argparse.Namespace) -> None:
    if args.plan is not None:
        from rllib_conv.common.config_files import read_yaml

        if Path(args.plan).is_dir():
            raise ValueError(f"--plan {args.plan!r} is a folder; expected a plan YAML file")
        read_yaml(args.plan, "--plan file")
    from analysis.report import build_report
    from rllib_conv.pipelines.reproduce import reproduce, stage_table

    reproduce(
        args.game, out=args.out, seeds=args.seeds, quick=args.quick, address=args.address, populations=args.populations,
        methods=args.methods, redo=args.redo, train_steps=args.train_steps, plan_file=args.plan, loggers=args.log,
    )
    print(stage_table(args.out).to_string(index=False))
    print(f"wrote {build_report(args.out)}")
    print(f"results in {args.out}")


def _cmd_report(args: argparse.Namespace) -> None:
    _check_report_inputs(args.root, args.user_study)
    from analysis.report import build_report

    print(f"wrote {build_report(args.root, args.out, args.user_study)}")


def _cmd_plot(args: argparse.Namespace) -> None:
    if not Path(args.folder).exists():
        raise ValueError(f"FOLDER {args.folder!r} does not exist; expected a training or sweep folder, an adaptation or zero-shot CSV, or a folder of them")
    plot_folder = _plot_folder()
    if plot_folder is None:
        raise RuntimeError("this installation has no figures (analysis/plots.py is missing)")
    for figure in plot_folder(Path(args.folder)):  # ValueError naming FOLDER when it holds nothing to plot
        print(f"wrote {figure}")


# --- the parser -----------------------------------------------------------------------------


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rllib-conv")
    except PackageNotFoundError:
        return "unknown (not installed)"


def _set_help(keys: dict[str, str]) -> str:
    """An epilog listing the `--set` keys of a command that no option sets."""
    width = max(map(len, keys))
    return "--set keys besides the options:\n" + "\n".join(f"  {k.ljust(width)}  {v}" for k, v in keys.items())


def _add_run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config value, VALUE in YAML, e.g. --set lam=0.3 or --set ppo.lr=1e-4 (repeatable)")
    p.add_argument("--storage", default="runs", help="folder for Tune's experiments and checkpoints (default: runs)")
    p.add_argument("--address", default=None, help="Ray cluster address (auto or HOST:PORT); default: $RAY_ADDRESS or a local Ray")


def _add_log_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--log", nargs="+", choices=LOGGERS, default=list(DEFAULT_LOGGERS), metavar="TRACKER",
        help="experiment tracking: tensorboard (event files in every trial folder, always written), wandb (offline "
        "unless $WANDB_MODE says otherwise; files in the experiment folder's wandb/), mlflow (a local store in its mlruns/); "
        "wandb and mlflow need pip install 'rllib-conv[tracking]' (default: tensorboard)",
    )


def _add_runs_args(p: argparse.ArgumentParser, out: str, what: str) -> None:
    """RUNS, and the name and folder of the CSV a command writes after them."""
    p.add_argument("runs", nargs="+", metavar="RUNS", help="trained-ego trial folders or experiment folders")
    p.add_argument("--name", help=f"name of the output CSV{what} (default: after RUNS and the options that differ)")
    p.add_argument("--out", default=out, help=f"folder for the CSV (default: {out})")


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of every subcommand."""
    raw_text = argparse.RawDescriptionHelpFormatter
    verbosity = _Parser(add_help=False)
    verbosity.add_argument("-v", "--verbose", action="store_true", help="show Ray's and Tune's own messages and warnings (hidden by default)")
    parser = _Parser(prog="rllib-conv", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"rllib-conv {_version()}", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name: str, help: str, func: Callable[[argparse.Namespace], None], group: Any = sub, **kwargs: Any) -> argparse.ArgumentParser:
        p = group.add_parser(name, help=help, description=kwargs.pop("description", help), parents=[verbosity], **kwargs)
        p.set_defaults(func=func)
        return p

    p = command("demo", "train the modular ego on the bandit (a few minutes) and show what it learned", _cmd_demo)
    _add_run_args(p)

    p = command("train", "train egos from an experiment YAML through Ray Tune", _cmd_train)
    p.add_argument("config", help="experiment YAML (see tune_configs/); results go to STORAGE/NAME/")
    _add_run_args(p)
    _add_log_arg(p)

    p = command(
        "sweep",
        "run a Tune grid (lam x method x population x seed) with a live table of trials; resumes when rerun",
        _cmd_train,
        description="Run the grid of an experiment YAML (any key may be {grid_search: [...]}). Checkpoints every "
        "run.checkpoint_every iterations, keeping run.keep_checkpoints. Results: STORAGE/NAME/<trial>/ "
        "(progress.csv, config.yaml, eval.json), read by `analysis.loaders.load_sweep`. Running the same command again, "
        "or with --resume, continues an interrupted sweep: finished trials are kept, the others continue from "
        "their last checkpoint.",
    )
    p.add_argument("config", help="experiment YAML with grid_search values (see tune_configs/)")
    p.add_argument("--resume", action="store_true", help="continue the sweep in STORAGE/NAME (an error if there is none)")
    _add_run_args(p)
    _add_log_arg(p)

    command("envs", "list the registered games", _cmd_envs)

    p = sub.add_parser("partners", help="partner populations: list, show, train", description="Partner populations: list, show, train.")
    psub = p.add_subparsers(dest="partners_command", required=True, metavar="COMMAND", parser_class=_Parser)

    command("list", "list the built-in populations", _cmd_partners_list, psub)
    q = command("show", "list a population's members: name (for --partner), split, kind, params", _cmd_partners_show, psub)
    q.add_argument("population", metavar="NAME", help="a built-in population name, a manifest file or a population folder")
    q = command("train", "train a self-play population from a YAML (see tune_configs/selfplay_*.yaml)", _cmd_partners_train, psub)
    q.add_argument("config", help="self-play YAML (see tune_configs/selfplay_*.yaml)")
    q.add_argument("--out", default="populations", help="folder for the population (default: populations)")
    q.add_argument("--overwrite", action="store_true", help="replace an existing population of the same name")
    _add_run_args(q)
    _add_log_arg(q)

    p = command(
        "adapt", "adapt trained egos to new partners (fresh head, task module kept, lam 0)", _cmd_adapt,
        epilog=_set_help(ADAPT_SET_KEYS), formatter_class=raw_text,
    )
    _add_runs_args(p, "adaptation", " and Tune experiment")
    p.add_argument("--partner", action="append", help="adapt to this partner only (repeatable; names: rllib-conv partners show POP); default: the --split")
    p.add_argument("--population", help="population of the new partners (default: the one each run trained on)")
    p.add_argument("--split", default="test", choices=["train", "test"], help="which partners of the population to adapt to (default: test)")
    p.add_argument("--method", choices=["scratch"], help="adapt a fresh network instead (learning from scratch)")
    p.add_argument("--frozen-task", action="store_true", help="keep the task module frozen while adapting")
    p.add_argument(
        "--head-init", default="fresh", choices=["fresh", "pick", "posterior"],
        help="pick: first try the fresh head and every training partner's head on the new partner, adapt from the best; "
        "posterior: adapt the fresh head and play by a posterior over which training partner's convention the new partner follows "
        "(both not in the paper)",
    )
    p.add_argument("--pick-steps", type=_positive_int, help="env steps spent picking the head (default: one update's worth)")
    p.add_argument(
        "--guard", action="store_true",
        help="evaluate the ego as it was before any update until the adapting one is measured better on its own rollouts "
        "(with --head-init fresh or posterior; not in the paper)",
    )
    _add_run_args(p)
    _add_log_arg(p)

    p = command(
        "zeroshot", "zero-shot coordination on the new task with known partners", _cmd_zeroshot,
        epilog=_set_help(ZEROSHOT_SET_KEYS), formatter_class=raw_text,
    )
    _add_runs_args(p, "zeroshot", " and Tune experiment")
    p.add_argument("--new-task", action="store_true", help="the new task is each run's population's -newtask variant (what happens without --new-population)")
    p.add_argument("--new-population", help="population of the same partners on the new task (default: POPULATION-newtask)")
    _add_run_args(p)
    _add_log_arg(p)

    p = command("marginals", "distance of each run's task module to the true marginals", _cmd_marginals)
    _add_runs_args(p, "marginals", "")
    p.add_argument("--episodes", type=_positive_int, default=200, help="episodes per training partner to collect states (non-bandit games; default 200)")
    p.add_argument("--seed", type=int, default=0, help="seed of those episodes (default 0)")

    p = command(
        "pair", "play any two players together (ego heads, task modules, population members, scripted partners)", _cmd_pair,
        description="Play fixed players, one per seat, for N episodes; write their mean return, its standard error "
        "and, on the bandit, the exact expected return to a CSV.",
        epilog=SEAT_SYNTAX, formatter_class=raw_text,
    )
    p.add_argument("seats", nargs="+", metavar="SEAT", help="one player per seat of the game, in the game's agent order (syntax below)")
    p.add_argument("--episodes", type=_positive_int, default=200, help="episodes to play (default 200)")
    p.add_argument("--seed", type=int, default=0, help="seed of the episodes and the players (default 0)")
    p.add_argument("--env", help="the game, when no seat names one or the seats name different ones")
    p.add_argument("--env-config", metavar="YAML", help="the game's settings as a YAML mapping, e.g. '{symmetric: 1}' (default: the seats')")
    p.add_argument("--name", help="name of the output CSV (default: after the seats)")
    p.add_argument("--out", default="pair", help="folder for the CSV (default: pair)")

    p = command("reproduce", "run every stage of the paper's experiments for a game (resumable)", _cmd_reproduce)
    p.add_argument("game", choices=["bandit", "blocks", "hanabi", "all"], help="the game whose experiments to run, or all three")
    p.add_argument("--seeds", type=_positive_int, default=3, help="seeds per method (default 3)")
    p.add_argument("--quick", action="store_true", help="a small version (1 seed, short runs) for demos and tests")
    p.add_argument("--out", default="reproduce", help="output folder (default: reproduce)")
    p.add_argument("--populations", nargs="+", metavar="NAME", help="only these populations (e.g. bandit-s2-hand bandit-s1-hand)")
    p.add_argument("--methods", nargs="+", metavar="LABEL", help="only these methods (e.g. agg maml; modular-lam0.5 is always run)")
    p.add_argument(
        "--redo", choices=["adapt", "zeroshot", "marginals"],
        help="run this finished stage again for the plan's experiments; their old outputs move to <out>/<game>/superseded/",
    )
    p.add_argument(
        "--train-steps", type=_positive_int, default=None, metavar="N",
        help="env steps each ego trains for (default: the paper's, e.g. blocks 1000000); a folder trained with another budget is refused",
    )
    p.add_argument(
        "--plan", default=None, metavar="FILE",
        help="a plan YAML to run instead of the shipped tune_configs/plan_GAME.yaml (copy and edit that file)",
    )
    p.add_argument("--address", default=None, help="Ray cluster address; default: $RAY_ADDRESS or a local Ray")
    _add_log_arg(p)

    from rllib_conv.play import command as play_command  # stdlib-only: the server loads when `play` runs

    p = sub.add_parser(
        "play", help="web page: people play the bandit study or blocks with the trained ego or each other", description=play_command.DESCRIPTION
    )
    play_command.add_arguments(p)
    p.add_argument("-v", dest="verbose", action="store_true", help="same as --verbose; also shows Ray's and Tune's warnings")
    p.set_defaults(func=_cmd_play)

    p = command("report", "build report.md (the paper's numbers beside ours, figures) from a reproduce folder", _cmd_report)
    p.add_argument("root", metavar="ROOT", help="a `reproduce --out` folder (one sub-folder per game) or one game folder")
    p.add_argument("--out", default=None, help="folder for report.md and figures/ (default: ROOT/report)")
    p.add_argument("--user-study", nargs="*", default=None, metavar="PATH", help="recorded session CSVs or folders (default: ROOT/user_study)")

    p = command("plot", "draw (again) the figures of a training or sweep folder, or of adaptation or zero-shot CSVs", _cmd_plot)
    p.add_argument("folder", metavar="FOLDER", help="a training or sweep folder (STORAGE/NAME), an adaptation or zero-shot CSV, or a folder of them")

    p = command("crossplay", "pair every member of population A (ego seat) with every member of B", _cmd_crossplay)
    p.add_argument("a", metavar="A", help="population name, manifest or folder (the ego seat)")
    p.add_argument("b", metavar="B", help="population name, manifest or folder (the partner seat)")
    p.add_argument("--episodes", type=_positive_int, default=100, help="episodes per pair (default 100)")
    p.add_argument("--seed", type=int, default=0, help="seed of the episodes (default 0)")
    p.add_argument("--out", default="crossplay", help="folder for the CSV and PNG (default: crossplay)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit status (0 ok, 1 a failed run, 2 bad input, 130 interrupted)."""
    args = build_parser().parse_args(argv)
    try:
        with _quiet(args.verbose, keep_logs=args.command == "play"):
            args.func(args)
    except KeyboardInterrupt as exc:
        print(f"rllib-conv: interrupted{': ' + _one_line(exc) if str(exc) else ''}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, yaml.YAMLError, FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError) as exc:
        print(f"rllib-conv: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except RuntimeError as exc:
        print(f"rllib-conv: error: {_one_line(exc)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
