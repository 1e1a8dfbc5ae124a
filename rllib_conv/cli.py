"""`rllib-conv`: the command line. Each subcommand parses arguments and calls one pipeline.

Bad input (an unknown env, population or config key, a missing file) prints one
`rllib-conv: error: ...` line and exits with status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Callable, Sequence

EXIT_USAGE = 2


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


def _cmd_demo(args: argparse.Namespace) -> None:
    from rllib_conv.pipelines.demo import demo

    demo(storage=args.storage, address=args.address, overrides=args.set)


def _cmd_train(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv.pipelines.train import run
    from rllib_conv.training import experiment

    raw = experiment.load(args.config, args.set)
    sweep = args.command == "sweep"
    results = run(raw, storage=args.storage, address=args.address, progress="table" if sweep else "lines", resume=sweep and args.resume)
    rows = []
    for r in results:
        m = r.metrics or {}
        cfg = r.config or {}
        rows.append(
            {
                "trial": Path(r.path).name,
                "method": cfg.get("method"),
                "lam": cfg.get("lam"),
                "population": cfg.get("population"),
                "seed": cfg.get("seed"),
                "env_steps": m.get("env_steps"),
                "return": m.get("return_mean"),
                "marginal_L1": m.get("eval/marginal_distance/paper"),
                "error": "yes" if r.error else "",
            }
        )
    with pd.option_context("display.width", 200, "display.max_colwidth", 60, "display.float_format", "{:.3f}".format):
        print(pd.DataFrame(rows).to_string(index=False))
    if results.errors:
        raise RuntimeError(f"{len(results.errors)} trial(s) failed; see the error.txt files under {args.storage}")


def _add_run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config value, e.g. --set lam=0.3 (repeatable)")
    p.add_argument("--storage", default="runs", help="folder for results and checkpoints (default: runs)")
    p.add_argument("--address", default=None, help="Ray cluster address (auto or HOST:PORT); default: $RAY_ADDRESS or a local Ray")


def _cmd_partners_train(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv.common import config_files
    from rllib_conv.pipelines.selfplay import train_population
    from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

    raw = config_files.load(args.config, args.set, schema=SelfPlayConfig)
    population, report = train_population(raw, out=args.out, storage=args.storage, address=args.address, overwrite=args.overwrite)
    with pd.option_context("display.width", 200, "display.float_format", "{:.3f}".format):
        print(report.to_string(index=False))
    failed = report.loc[~report["passed"].astype(bool), "partner"].tolist()
    print(f"population {population.name!r}: {len(population.partners)} partners kept in {Path(args.out) / population.name}")
    if failed:
        print(f"not kept (did not reach the gate): {', '.join(failed)}")


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


def _cmd_adapt(args: argparse.Namespace) -> None:
    from rllib_conv.common import config_files
    from rllib_conv.pipelines.adapt import run_adaptation
    from rllib_conv.pipelines.adapt_config import AdaptConfig

    raw = {"name": args.name, "runs": args.runs, "split": args.split, "train_task": not args.frozen_task, "head_init": args.head_init}
    options = {"population": args.population, "partners": args.partner, "method": args.method, "pick_steps": args.pick_steps}
    raw.update({k: v for k, v in options.items() if v is not None})
    raw = config_files.from_dict(raw, args.set, schema=AdaptConfig)
    curves = run_adaptation(raw, out=args.out, storage=args.storage, address=args.address)
    summary = curves.groupby(["method", "lam", "steps"])[["mean_return", "exact_return"]].mean().unstack("steps")
    print(summary.round(3).to_string())
    print(f"wrote {Path(args.out) / (args.name + '.csv')}")


def _cmd_zeroshot(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv.common import config_files
    from rllib_conv.pipelines.zeroshot import run_zeroshot
    from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig

    raw = {"name": args.name, "runs": args.runs}
    if args.new_population:
        raw["new_population"] = args.new_population
    raw = config_files.from_dict(raw, args.set, schema=ZeroShotConfig)
    table = run_zeroshot(raw, out=args.out, storage=args.storage, address=args.address)
    with pd.option_context("display.width", 200, "display.max_colwidth", 60, "display.float_format", "{:.3f}".format):
        print(table.drop(columns=["run"]).to_string(index=False))
    print(f"wrote {Path(args.out) / (args.name + '.csv')}")


def _cmd_marginals(args: argparse.Namespace) -> None:
    import pandas as pd

    from rllib_conv.common.run_folders import trial_folders
    from rllib_conv.pipelines.marginals import marginal_report

    table = marginal_report([t for run in args.runs for t in trial_folders(run)], episodes=args.episodes, seed=args.seed)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    table.to_csv(args.out, index=False)
    with pd.option_context("display.width", 200, "display.float_format", "{:.3f}".format):
        print(table.drop(columns=["run"]).to_string(index=False))
    print(f"wrote {args.out}")


def _cmd_play(args: argparse.Namespace) -> None:
    from rllib_conv.play.command import run

    run(args)


def _cmd_reproduce(args: argparse.Namespace) -> None:
    from analysis.report import build_report
    from rllib_conv.pipelines.reproduce import reproduce, stage_table

    reproduce(
        args.game, out=args.out, seeds=args.seeds, quick=args.quick, address=args.address, populations=args.populations,
        methods=args.methods, redo=args.redo, train_steps=args.train_steps, plan_file=args.plan,
    )
    print(f"report: {build_report(args.out)}")
    print(stage_table(args.out).to_string(index=False))


def _cmd_report(args: argparse.Namespace) -> None:
    from analysis.report import build_report

    print(build_report(args.root, args.out, args.user_study))


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of every subcommand."""
    parser = argparse.ArgumentParser(prog="rllib-conv", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="train the modular ego on the bandit (a few minutes) and show what it learned")
    _add_run_args(p)
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("train", help="train the ego from an experiment YAML through Ray Tune")
    p.add_argument("config", help="experiment YAML (see tune_configs/)")
    _add_run_args(p)
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser(
        "sweep",
        help="run a Tune grid (lam x method x population x seed) with a live table of trials; resumes when rerun",
        description="Run the grid of an experiment YAML (any key may be {grid_search: [...]}). Checkpoints every "
        "run.checkpoint_every iterations, keeping run.keep_checkpoints. Results: STORAGE/NAME/<trial>/ "
        "(progress.csv, config.yaml, eval.json), read by `analysis.loaders.load_sweep`. Running the same command again, "
        "or with --resume, continues an interrupted sweep: finished trials are kept, the others continue from "
        "their last checkpoint.",
    )
    p.add_argument("config", help="experiment YAML with grid_search values (see tune_configs/)")
    p.add_argument("--resume", action="store_true", help="continue the sweep in STORAGE/NAME (an error if there is none)")
    _add_run_args(p)
    p.set_defaults(func=_cmd_train)

    p = sub.add_parser("envs", help="list the registered games")
    p.set_defaults(func=_cmd_envs)

    p = sub.add_parser("partners", help="partner populations")
    psub = p.add_subparsers(dest="partners_command", required=True)
    pl = psub.add_parser("list", help="list the built-in populations")
    pl.set_defaults(func=_cmd_partners_list)
    pt = psub.add_parser("train", help="train a self-play population from a YAML (see tune_configs/selfplay_*.yaml)")
    pt.add_argument("config")
    pt.add_argument("--out", default="populations", help="folder for the population (default: populations)")
    pt.add_argument("--overwrite", action="store_true", help="replace an existing population of the same name")
    _add_run_args(pt)
    pt.set_defaults(func=_cmd_partners_train)

    p = sub.add_parser("adapt", help="adapt trained egos to new partners (fresh head, task module kept, lam 0)")
    p.add_argument("runs", nargs="+", help="trained-ego trial folders or experiment folders")
    p.add_argument("--partner", action="append", help="adapt to this partner only (repeatable); default: the test split")
    p.add_argument("--population", help="population of the new partners (default: the one each run trained on)")
    p.add_argument("--split", default="test", choices=["train", "test"])
    p.add_argument("--method", choices=["scratch"], help="adapt a fresh network instead (learning from scratch)")
    p.add_argument("--frozen-task", action="store_true", help="keep the task module frozen while adapting")
    p.add_argument(
        "--head-init", default="fresh", choices=["fresh", "pick"],
        help="pick: first try the fresh head and every training partner's head on the new partner, adapt from the best (not in the paper)",
    )
    p.add_argument("--pick-steps", type=int, help="env steps spent picking the head (default: one update's worth)")
    p.add_argument("--name", default="adapt", help="name of the output CSV and Tune run")
    p.add_argument("--out", default="adaptation", help="folder for the curves CSV (default: adaptation)")
    _add_run_args(p)
    p.set_defaults(func=_cmd_adapt)

    p = sub.add_parser("zeroshot", help="zero-shot coordination on the new task with known partners")
    p.add_argument("runs", nargs="+", help="trained-ego trial folders or experiment folders")
    p.add_argument("--new-task", action="store_true", help="use the runs' population's -newtask variant (the default)")
    p.add_argument("--new-population", help="population of the same partners on the new task")
    p.add_argument("--name", default="zeroshot")
    p.add_argument("--out", default="zeroshot", help="folder for the results CSV (default: zeroshot)")
    _add_run_args(p)
    p.set_defaults(func=_cmd_zeroshot)

    p = sub.add_parser("marginals", help="distance of each run's task module to the true marginals")
    p.add_argument("runs", nargs="+", help="trained-ego trial folders or experiment folders")
    p.add_argument("--episodes", type=int, default=200, help="episodes per training partner to collect states (non-bandit games)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="marginals/marginals.csv")
    p.set_defaults(func=_cmd_marginals)

    p = sub.add_parser("reproduce", help="run every stage of the paper's experiments for a game (resumable)")
    p.add_argument("game", choices=["bandit", "blocks", "hanabi", "all"])
    p.add_argument("--seeds", type=int, default=3, help="seeds per method (default 3)")
    p.add_argument("--quick", action="store_true", help="a small version (1 seed, short runs) for demos and tests")
    p.add_argument("--out", default="reproduce", help="output folder (default: reproduce)")
    p.add_argument("--populations", nargs="+", metavar="NAME", help="only these populations (e.g. bandit-s2-hand bandit-s1-hand)")
    p.add_argument("--methods", nargs="+", metavar="LABEL", help="only these methods (e.g. agg maml; modular-lam0.5 is always run)")
    p.add_argument(
        "--redo", choices=["adapt", "zeroshot", "marginals"],
        help="run this finished stage again for the plan's experiments; their old outputs move to <out>/<game>/superseded/",
    )
    p.add_argument(
        "--train-steps", type=int, default=None, metavar="N",
        help="env steps each ego trains for (default: the paper's, e.g. blocks 1000000); a folder trained with another budget is refused",
    )
    p.add_argument(
        "--plan", default=None, metavar="FILE",
        help="a plan YAML to run instead of the shipped tune_configs/plan_GAME.yaml (copy and edit that file)",
    )
    p.add_argument("--address", default=None, help="Ray cluster address; default: $RAY_ADDRESS or a local Ray")
    p.set_defaults(func=_cmd_reproduce)

    from rllib_conv.play import command as play_command  # stdlib-only: the server loads when `play` runs

    p = sub.add_parser("play", help="web page: people play the bandit study or blocks with the trained ego or each other", description=play_command.DESCRIPTION)
    play_command.add_arguments(p)
    p.set_defaults(func=_cmd_play)

    p = sub.add_parser("report", help="build report.md (the paper's numbers beside ours, figures) from a reproduce folder")
    p.add_argument("root", help="a `reproduce --out` folder (one sub-folder per game) or one game folder")
    p.add_argument("--out", default=None, help="folder for report.md and figures/ (default: ROOT/report)")
    p.add_argument("--user-study", nargs="*", default=None, metavar="PATH", help="recorded session CSVs or folders (default: ROOT/user_study)")
    p.set_defaults(func=_cmd_report)

    p = sub.add_parser("crossplay", help="pair every member of population A (ego seat) with every member of B")
    p.add_argument("a", help="population name, manifest or folder")
    p.add_argument("b", help="population name, manifest or folder")
    p.add_argument("--episodes", type=int, default=100, help="episodes per pair (default 100)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="crossplay", help="folder for the CSV and PNG (default: crossplay)")
    p.set_defaults(func=_cmd_crossplay)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit status (0 ok, 2 bad input)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    func: Callable[[argparse.Namespace], None] = args.func
    try:
        func(args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"rllib-conv: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except RuntimeError as exc:
        print(f"rllib-conv: error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
