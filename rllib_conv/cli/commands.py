"""What each `rllib-conv` subcommand does: check its arguments and outputs, call one pipeline, say where the results went.

Checks come first and use light imports (pydantic, YAML, the env registry; no torch, no
Ray): a refused command answers at once and writes nothing. The validation itself is
`common.config_files.check` (it blames `--set`, an option or the file), output names are
`pipelines.naming`'s, and the pipelines write their own files; what is left here is
arguments in, printed tables and `wrote <path>` lines out.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import importlib.util
import json
import logging
import os
import sys
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import yaml

from rllib_conv import partners
from rllib_conv.common import config_files
from rllib_conv.common.run_folders import ADAPT_PREFIX, EVAL_FILE, POPULATION_FILE, SPEC_FILE, ZEROSHOT_PREFIX, trial_folders
from rllib_conv.partners.population import refuse_existing
from rllib_conv.pipelines import naming
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.evaluate_config import EvaluateConfig
from rllib_conv.pipelines.evaluate_config import check as check_evaluation
from rllib_conv.pipelines.pair_config import PairConfig, is_run, population_seat, split_seat
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig
from rllib_conv.training.experiment import ExperimentConfig, check_trial

MAX_PORT = 65535
WARN = "rllib-conv: warning:"
# The key each adapt / zeroshot option sets (the help lists the others as `--set` keys).
ADAPT_OPTIONS = {
    "name": "--name",
    "runs": "RUNS",
    "population": "--population",
    "split": "--split",
    "partners": "--partner",
    "method": "--method",
    "train_task": "--frozen-task",
    "head_init": "--head-init",
    "pick_steps": "--pick-steps",
    "guard": "--guard",
}
ZEROSHOT_OPTIONS = {"name": "--name", "runs": "RUNS", "new_population": "--new-population"}
# What `-v` would show: Tune's experiment box and its TensorBoard hint into Ray's temporary
# folder (our own lines say where results go), Ray's token-auth and deprecation warnings
# (driver and workers), Python warnings in the workers Ray starts.
QUIET_ENV = {"RAY_AIR_NEW_OUTPUT": "0", "RAY_LOGGER_LEVEL": "error", "PYTHONWARNINGS": "ignore"}


@contextlib.contextmanager
def quiet(verbose: bool, keep_logs: bool = False) -> Iterator[None]:
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


# --- checks before any work -------------------------------------------------------------------


def trials(runs: Sequence[str]) -> list[Path]:
    """Every trained-ego trial folder of the RUNS arguments, each checked (`training.experiment.check_trial`)."""
    found = [t for run in runs for t in trial_folders(run)]
    for trial in found:
        check_trial(trial)
    return found


def writable(path: str | Path, option: str) -> Path:
    """`path` as a folder this process may create or write in; ValueError naming `option` otherwise (nothing created)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise ValueError(f"{option} {str(path)!r} is a file; expected a folder")
    existing = next(p for p in (path, *path.absolute().parents) if p.exists())
    if not existing.is_dir():
        raise ValueError(f"{option} {str(path)!r}: {str(existing)!r} is a file, so no folder can be made below it")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"{option} {str(path)!r}: no permission to write in {str(existing)!r}")
    return path


def _given(values: dict[str, Any], options: dict[str, str]) -> dict[tuple[str, ...], str]:
    """Key path -> option, for the options the user gave (`values` None where not: an option left unset takes no blame)."""
    return {(key,): options[key] for key, value in values.items() if value is not None}


def _note_reuse(folder: Path, spec: dict[str, Any], egos: int | None = None) -> None:
    """Say so when `folder` already holds this very experiment: Tune continues it instead of starting over."""
    path = folder / SPEC_FILE
    if not path.is_file() or yaml.safe_load(path.read_text()) != spec:
        return  # nothing there, or another experiment (the pipeline refuses that one)
    done = ""
    if egos:
        finished = sum((t / EVAL_FILE).is_file() for t in trial_folders(folder, missing_ok=True))
        done = f" ({finished} of {egos} trained egos finished)"
    print(
        f"note: {folder} already holds this experiment{done}: finished trials are kept, not run again, and unfinished ones continue; delete the folder to start over"
    )


def check_report_inputs(root: str | Path, user_study: Sequence[str] | None) -> None:
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


# --- printing results ---------------------------------------------------------------------


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
        print(f"{WARN} no figures for {path}: {' '.join(str(exc).split())} (`rllib-conv plot {path}` retries)", file=sys.stderr)
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


def adapt_summary(curves: Any) -> Any:
    """The adaptation curves as one narrow table: env steps down, per (method, lam) the mean return (and exact, on the bandit)."""
    curves = curves.assign(label=curves["method"].astype(str) + " lam " + curves["lam"].astype(str))
    metrics = [(key, short) for key, short in (("mean_return", "return"), ("exact_return", "exact")) if curves[key].notna().any()]
    table = curves.pivot_table(index="steps", columns="label", values=[key for key, _ in metrics], aggfunc="mean")
    names = dict(metrics)
    table.columns = [f"{label} {names[key]}" for key, label in table.columns]
    order = [f"{label} {short}" for label in sorted(curves["label"].unique()) for _, short in metrics]
    return table[order].reset_index()


# --- the commands -------------------------------------------------------------------------


def envs_list(args: argparse.Namespace) -> None:
    """`rllib-conv envs`: the registered games, one a line."""
    from rllib_conv import envs

    for name in envs.names():
        print(name)


def partners_list(args: argparse.Namespace) -> None:
    """`rllib-conv partners list`: the built-in populations and their sizes."""
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


def partners_show(args: argparse.Namespace) -> None:
    """`rllib-conv partners show NAME`: one population's members."""
    import pandas as pd

    from rllib_conv import partners

    pop = partners.get(args.population)
    print(f"{pop.name}: {pop.env} {pop.env_config}, partners in seat {', '.join(pop.partner_agents)}")
    if pop.description:
        print(pop.description)
    rows = [
        {
            "partner": e.name,
            "split": e.split,
            "kind": e.kind,
            "params": json.dumps(e.params),
            **({"hidden_utility": json.dumps(e.hidden_utility)} if e.hidden_utility else {}),  # HSP's weights
        }
        for e in pop.partners
    ]
    with pd.option_context("display.max_colwidth", 100, "display.width", 200):
        print(pd.DataFrame(rows).to_string(index=False))


def demo(args: argparse.Namespace) -> None:
    """`rllib-conv demo`: train the bandit's modular ego and show what it learned."""
    from rllib_conv.common.resources import config_file

    config = config_files.load_checked(config_file("bandit_modular.yaml"), ["name=demo", *args.set], schema=ExperimentConfig)
    _note_reuse(writable(args.storage, "--storage") / "demo", config.raw, egos=1)
    from rllib_conv.pipelines.demo import demo as run_demo

    run_demo(config, storage=args.storage, address=args.address)
    print(f"results in {Path(args.storage) / 'demo'}")


def train(args: argparse.Namespace) -> None:
    """`rllib-conv train` and `sweep`: train the egos of an experiment YAML; a table of trials."""
    config = config_files.load_checked(args.config, args.set, schema=ExperimentConfig)
    raw, variants = config.raw, config.variants
    folder = writable(args.storage, "--storage") / variants[0].name
    sweep = args.command == "sweep"
    if sweep and args.resume and not (folder / SPEC_FILE).is_file():
        raise ValueError(f"--resume: {str(folder)!r} holds no sweep to resume (run without --resume to start it)")
    # A misspelt name fails here, in a second, not after torch and Ray load; blamed on where it came from.
    source = next((f"--set {s}" for s in reversed(args.set) if s.split("=", 1)[0].strip() == "population"), str(args.config))
    for population in dict.fromkeys(v.population for v in variants):
        try:
            partners.get(population)
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None
    _note_reuse(folder, raw, egos=len(variants))
    import pandas as pd

    from rllib_conv.pipelines.train import run

    results = run(
        config,
        storage=args.storage,
        address=args.address,
        progress="table" if sweep else "lines",
        resume=sweep and args.resume,
        loggers=args.log,
    )
    rows = []
    for r in results:
        m, cfg = r.metrics or {}, r.config or {}  # the trial's values; unset ones are the schema's defaults
        row = {"trial": naming.trial_id(Path(r.path))}
        row |= {k: cfg.get(k, ExperimentConfig.model_fields[k].default) for k in ("population", "method", "lam", "seed")}
        row |= {
            "env_steps": m.get("env_steps"),
            "return": m.get("return_mean"),
            "marginal_L1": m.get("eval/marginal_distance/paper"),
        }
        rows.append({**row, "error": "yes" if r.error else ""})
    print(_table(pd.DataFrame(rows)))
    if results.errors:
        raise RuntimeError(f"{len(results.errors)} trial(s) failed; see the error.txt files under {folder}")
    for figure in _figures(folder):
        print(f"figure: {figure}")
    print(f"TensorBoard: tensorboard --logdir {folder}")
    print(f"results in {folder}")


def partners_train(args: argparse.Namespace) -> None:
    """`rllib-conv partners train`: a self-play population, keeping the pairs that reach the gate."""
    from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

    config = config_files.load_checked(args.config, args.set, schema=SelfPlayConfig)
    target = writable(args.out, "--out") / config.first.name
    writable(args.storage, "--storage")
    refuse_existing(target, args.overwrite)
    from rllib_conv.pipelines.selfplay import train_population

    population, report = train_population(
        config, out=args.out, storage=args.storage, address=args.address, overwrite=args.overwrite, loggers=args.log
    )
    print(_table(report))
    failed = report.loc[~report["passed"].astype(bool), "partner"].tolist()
    if failed:
        print(f"not kept (did not reach the gate): {', '.join(failed)}")
    print(f"population {population.name!r}: {len(population.partners)} partners kept")
    print(f"wrote {target}")


def partners_from_set(args: argparse.Namespace) -> None:
    """`rllib-conv partners from-set SET`: an evaluation set's partners as a population whose every member trains."""
    from rllib_conv.partners.evaluation_sets import set_named

    population = set_named(args.set).training_population(args.name)
    target = writable(args.out, "--out") / population.name
    refuse_existing(target, args.overwrite, "--name")
    population.save(target / POPULATION_FILE)
    print(f"population {population.name!r}: {len(population.partners)} partners to train with ({population.description})")
    print(f"wrote {target / POPULATION_FILE}")


def partners_prune(args: argparse.Namespace) -> None:
    """`rllib-conv partners prune NAME --keep K`: a self-play population cut to its K most diverse training pairs."""
    from rllib_conv.pipelines.prune import PRUNE_REPORT_FILE, prune, pruned_name, write_pruned

    out = writable(args.out, "--out")
    source = partners.get(args.population)
    target = out / (args.name or pruned_name(source, args.keep))
    refuse_existing(target, args.overwrite, "--name")  # before the episodes are played
    population, report = prune(source, args.keep, args.episodes, args.seed, target.name)
    write_pruned(population, report, target)
    kept = report.sort_values("order").loc[report["kept"], "partner"]
    print(f"population {population.name!r}: kept {', '.join(kept)} of {len(report)} training pairs, most diverse first")
    print(f"wrote {target / POPULATION_FILE} and {target / PRUNE_REPORT_FILE}")


def crossplay(args: argparse.Namespace) -> None:
    """`rllib-conv crossplay A B`: every member of A with every member of B; a CSV and a PNG."""
    writable(args.out, "--out")
    import pandas as pd

    from rllib_conv import partners
    from rllib_conv.pipelines.crossplay import crossplay as run_crossplay
    from rllib_conv.pipelines.crossplay import crossplay_gap, write_crossplay

    a, b = partners.get(args.a), partners.get(args.b)
    matrix = run_crossplay(a, b, episodes=args.episodes, seed=args.seed)
    csv, png = write_crossplay(matrix, args.out, f"{a.name}__{b.name}")
    with pd.option_context("display.width", 250, "display.float_format", "{:.2f}".format):
        print(matrix.to_string())
    gap = crossplay_gap(matrix)
    if gap is not None:
        print(f"self-play {gap['selfplay']:.3f}, cross-play {gap['crossplay']:.3f}: cross-play gap {gap['gap']:.3f}")
    print(f"wrote {csv} and {png}")


def adapt(args: argparse.Namespace) -> None:
    """`rllib-conv adapt RUNS`: adaptation curves with new partners; a CSV named after the inputs."""
    trials(args.runs)
    options = {  # what the user gave (None: left unset, so it takes no blame)
        "name": args.name,
        "population": args.population,
        "partners": args.partner,
        "method": args.method,
        "head_init": None if args.head_init == "fresh" else args.head_init,
        "pick_steps": args.pick_steps,
        "guard": args.guard or None,
    }
    name = args.name or naming.adapt_name(
        args.runs,
        method=args.method,
        head_init=args.head_init,
        pick_steps=args.pick_steps,
        frozen_task=args.frozen_task,
        guard=args.guard,
        split=args.split,
        population=args.population,
        partners=args.partner or (),
        sets=args.set,
    )
    raw = {"name": name, "runs": args.runs, "split": args.split, "train_task": not args.frozen_task, "head_init": args.head_init}
    raw.update({k: v for k, v in options.items() if v is not None})
    config = config_files.with_sets(raw, args.set, AdaptConfig, _given(options, ADAPT_OPTIONS), "arguments")
    out, storage = writable(args.out, "--out"), writable(args.storage, "--storage")
    _note_reuse(storage / f"{ADAPT_PREFIX}{name}", config.raw)
    from rllib_conv.pipelines.adapt import run_adaptation

    curves = run_adaptation(config, out=out, storage=storage, address=args.address, loggers=args.log)
    print("mean over partners and seeds, by env steps:")
    print(_table(adapt_summary(curves)))
    _wrote_with_figures(out / f"{name}.csv")


def zeroshot(args: argparse.Namespace) -> None:
    """`rllib-conv zeroshot RUNS`: the paper's three zero-shot steps; a CSV named after the inputs."""
    trials(args.runs)
    name = args.name or naming.zeroshot_name(args.runs, new_population=args.new_population, sets=args.set)
    options = {"name": args.name, "new_population": args.new_population}
    raw = {"name": name, "runs": args.runs} | ({"new_population": args.new_population} if args.new_population else {})
    config = config_files.with_sets(raw, args.set, ZeroShotConfig, _given(options, ZEROSHOT_OPTIONS), "arguments")
    out, storage = writable(args.out, "--out"), writable(args.storage, "--storage")
    _note_reuse(storage / f"{ZEROSHOT_PREFIX}{name}", config.raw)
    from rllib_conv.pipelines.zeroshot import run_zeroshot

    table = run_zeroshot(config, out=out, storage=storage, address=args.address, loggers=args.log)
    print(_table(table.drop(columns=["run"])))
    _wrote_with_figures(out / f"{name}.csv")


def marginals(args: argparse.Namespace) -> None:
    """`rllib-conv marginals RUNS`: each task module's distance to the true marginals; a CSV."""
    found = trials(args.runs)
    name = naming.slug(args.name) if args.name else naming.marginals_name(args.runs, episodes=args.episodes, seed=args.seed)
    path = writable(args.out, "--out") / f"{name}.csv"
    from rllib_conv.pipelines.marginal_report import write_marginal_report

    table = write_marginal_report(found, path, episodes=args.episodes, seed=args.seed)
    print(_table(table.drop(columns=["run"])))
    print(f"wrote {path}")


def pair(args: argparse.Namespace) -> None:
    """`rllib-conv pair SEAT SEAT`: fixed players together for N episodes; a one-row CSV."""
    env_config = None if args.env_config is None else config_files.yaml_value(args.env_config, "--env-config")
    raw = {"seats": args.seats, "episodes": args.episodes, "seed": args.seed, "env": args.env, "env_config": env_config}
    origins = {("seats",): "SEATS", ("env",): "--env", ("env_config",): "--env-config", ("episodes",): "--episodes"}
    cfg = config_files.check(raw, PairConfig, origins)[0]
    labels = []
    for text in cfg.seats:
        source, what = split_seat(text)
        if is_run(source):
            trials([source])
        elif source not in partners.kinds():
            population_seat(text)
        labels.append(naming.seat_label(source, what, is_run(source)))
    path = writable(args.out, "--out") / f"{naming.slug(args.name or '__'.join(labels))}.csv"
    from rllib_conv.pipelines.pair import write_pair

    table = write_pair(cfg, path)
    print(_table(table.T.reset_index().set_axis(["", "value"], axis=1), width=250))
    print(f"wrote {path}")


def evaluate(args: argparse.Namespace) -> None:
    """`rllib-conv evaluate RUNS`: egos against an evaluation set; scores.csv, summary.json, summary.png and a table."""
    keys = ("runs", "eval_set", "module", "episodes", "seed", "resamples", "confidence")
    raw = {k: getattr(args, k) for k in keys if getattr(args, k) is not None}
    origins = {(k,): "RUNS" if k == "runs" else f"--{k.replace('_', '-')}" for k in keys}
    cfg = config_files.check(raw, EvaluateConfig, origins)[0]
    found = check_evaluation(cfg)
    name = (
        naming.slug(args.name)
        if args.name
        else naming.evaluate_name(cfg.runs, eval_set=cfg.eval_set, module=cfg.module, episodes=cfg.episodes, seed=cfg.seed)
    )
    folder = writable(Path(args.out) / name, "--out")  # OUT/NAME itself: a file there is refused before any work
    from rllib_conv.pipelines.evaluate import FIGURE_FILE, SCORES_FILE, SUMMARY_FILE, write_evaluation

    table, summary = write_evaluation(cfg, found, folder, ["rllib-conv", *args.argv])
    by_partner = table.groupby(["agent", "partner"], sort=False)[["bound", "return", "normalised"]].mean().reset_index()
    print(f"{found.eval_set.name} ({found.env} {found.env_config}): mean over seeds, by partner")
    print(_table(by_partner))
    print(f"\nnormalised score per agent, {cfg.confidence:.0%} bootstrap intervals over seeds:")
    print(_table(summary))
    print(f"wrote {folder / SCORES_FILE}, {folder / SUMMARY_FILE} and {folder / FIGURE_FILE}")


def human_data(args: argparse.Namespace) -> None:
    """`rllib-conv human-data overcooked`: fetch and convert the 2019 human trials into the cache; a table of what is there."""
    # Loaded here: it needs the `overcooked` extra, which the other commands do not.
    from rllib_conv.envs.overcooked import human_data as data

    unknown = [layout for layout in args.layouts or [] if layout not in data.LAYOUTS]
    if unknown:
        raise ValueError(f"--layouts: unknown layout {unknown[0]!r}; the human data covers {', '.join(data.LAYOUTS)}")
    paths = data.convert(args.cache, args.layouts)
    print(_table(data.summary(args.cache, args.layouts)))
    print(f"results in {data.cache_folder(args.cache) / 'trajectories'} ({len(paths)} files)")


def human_proxies(args: argparse.Namespace) -> None:
    """`rllib-conv human-proxies overcooked`: behaviour-cloned BC and H_proxy per layout and seed, into the cache; their table."""
    # Loaded here: it needs the `overcooked` extra, which the other commands do not.
    from rllib_conv.pipelines import human_proxies as proxies

    table = proxies.run(args.layouts, seeds=args.seeds, cache=args.cache, episodes=args.episodes, progress=True)
    shown = ["layout", "seed", "bc_accuracy_moves_test_split", "hproxy_accuracy_moves_train_split", "return_bc_hproxy"]
    print(_table(table[[*shown, "return_bc_bc", "human_return_test"]]))
    print(f"wrote {proxies.report_path(args.cache)} (every accuracy, time and return)")


def play(args: argparse.Namespace) -> None:
    """`rllib-conv play`: the study server (its own options: `rllib_conv.play.command`)."""
    if not 0 <= args.port <= MAX_PORT:
        raise ValueError(f"--port: expected a port 0-{MAX_PORT} (0 picks a free one), got {args.port}")
    if args.run is not None and Path(args.run).is_dir():  # the ego's trial folder (its agents and test runs: play checks them)
        trials([args.run])
    from rllib_conv.play.command import run as run_play

    try:
        run_play(args)
    except OSError as exc:
        if exc.errno in (errno.EADDRINUSE, errno.EACCES):
            raise ValueError(f"--port {args.port}: {exc.strerror} (choose another port, or 0 for a free one)") from None
        raise


def reproduce(args: argparse.Namespace) -> None:
    """`rllib-conv reproduce GAME`: every stage of the paper's experiments, then the report."""
    if args.plan is not None:
        config_files.read_yaml(args.plan, "--plan file")
    writable(args.out, "--out")
    from analysis.report import build_report
    from rllib_conv.pipelines.reproduce import reproduce as run_reproduce
    from rllib_conv.pipelines.reproduce import stage_table

    run_reproduce(
        args.game,
        out=args.out,
        seeds=args.seeds,
        quick=args.quick,
        address=args.address,
        populations=args.populations,
        methods=args.methods,
        redo=args.redo,
        train_steps=args.train_steps,
        plan_file=args.plan,
        loggers=args.log,
    )
    print(stage_table(args.out).to_string(index=False))
    print(f"wrote {build_report(args.out)}")
    print(f"results in {args.out}")


def report(args: argparse.Namespace) -> None:
    """`rllib-conv report ROOT`: report.md and figures of a reproduction."""
    check_report_inputs(args.root, args.user_study)
    if args.out is not None:
        writable(args.out, "--out")
    from analysis.report import build_report

    print(f"wrote {build_report(args.root, args.out, args.user_study)}")


def plot(args: argparse.Namespace) -> None:
    """`rllib-conv plot FOLDER`: draw the figures of a training folder or stage CSVs again."""
    if not Path(args.folder).exists():
        raise ValueError(
            f"FOLDER {args.folder!r} does not exist; expected a training or sweep folder, an adaptation or zero-shot CSV, or a folder of them"
        )
    plot_folder = _plot_folder()
    if plot_folder is None:
        raise RuntimeError("this installation has no figures (analysis/plots.py is missing)")
    for figure in plot_folder(Path(args.folder)):  # ValueError naming FOLDER when it holds nothing to plot
        print(f"wrote {figure}")
