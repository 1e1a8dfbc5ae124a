"""`rllib-conv`: the command line. Each subcommand checks its arguments, calls one pipeline and says where its results went.

Bad input (an out-of-range option, an unknown env, population or config key, a missing or
malformed file, an output folder it cannot write) prints one `rllib-conv: error: ...` line
naming the argument, `--set` or file and exits with status 2, before anything is written.
Arguments and files are checked with light imports (pydantic, YAML, the env registry; no
torch, no Ray), so `--help` and such errors answer at once; a pipeline loads only when
there is work to do. Ray's and Tune's own messages are hidden unless `-v` is given. Every
command that writes ends with one line saying where: `wrote <path>` or `results in <folder>`.
This module is the parser, one builder per command; `commands` does each command's work, and
`arguments` holds the shared options and the help texts taken from the schemas.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any, Callable, Sequence

import yaml
from pydantic import ValidationError

from rllib_conv.cli import commands
from rllib_conv.cli.arguments import (
    ADAPT_SET_KEYS,
    EXIT_USAGE,
    GENERATOR_KEYS,
    ZEROSHOT_SET_KEYS,
    Parser,
    described,
    keys_help,
    log_arg,
    positive_int,
    run_args,
    runs_args,
    set_help,
)
from rllib_conv.cli.commands import ADAPT_OPTIONS, ZEROSHOT_OPTIONS, check_report_inputs
from rllib_conv.cli.human_data import human_data_parsers
from rllib_conv.common.config_files import describe
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.evaluate_config import EvaluateConfig
from rllib_conv.pipelines.pair_config import SEAT_SYNTAX, PairConfig
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig

__all__ = ["ADAPT_SET_KEYS", "EXIT_INTERRUPTED", "EXIT_USAGE", "ZEROSHOT_SET_KEYS", "build_parser", "main"]
EXIT_INTERRUPTED = 130
_check_report_inputs = check_report_inputs  # the name the tests and older callers use


def _one_line(exc: BaseException) -> str:
    """The exception's message on one line (pydantic errors as `key: problem` clauses)."""
    return describe(exc) if isinstance(exc, ValidationError) else " ".join(str(exc).split())


# --- the parser: one builder per command -----------------------------------------------------------


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rllib-conv")
    except PackageNotFoundError:
        return "unknown (not installed)"


def _train(command: Callable[..., argparse.ArgumentParser]) -> None:
    p = command("demo", "train the modular ego on the bandit (a few minutes) and show what it learned", commands.demo)
    run_args(p)
    p = command("train", "train egos from an experiment YAML through Ray Tune", commands.train)
    p.add_argument("config", help="experiment YAML (see tune_configs/); results go to STORAGE/NAME/")
    run_args(p), log_arg(p)
    p = command(
        "sweep",
        "run a Tune grid (lam x method x population x seed) with a live table of trials; resumes when rerun",
        commands.train,
        description="Run the grid of an experiment YAML (any key may be {grid_search: [...]}). Checkpoints every "
        "run.checkpoint_every iterations, keeping run.keep_checkpoints. Results: STORAGE/NAME/<trial>/ "
        "(progress.csv, config.yaml, eval.json), read by `analysis.loaders.load_sweep`. Running the same command again, "
        "or with --resume, continues an interrupted sweep: finished trials are kept, the others continue from their last checkpoint.",
    )
    p.add_argument("config", help="experiment YAML with grid_search values (see tune_configs/)")
    p.add_argument("--resume", action="store_true", help="continue the sweep in STORAGE/NAME (an error if there is none)")
    run_args(p), log_arg(p)
    command("envs", "list the registered games", commands.envs_list)


def _partners(sub: Any, command: Callable[..., argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "partners",
        help="partner populations: list, show, train, from-set, prune",
        description="Partner populations: list, show, train, from-set, prune.",
    )
    psub = p.add_subparsers(dest="partners_command", required=True, metavar="COMMAND", parser_class=Parser)
    command("list", "list the built-in populations", commands.partners_list, psub)
    q = command("show", "list a population's members: name (for --partner), split, kind, params", commands.partners_show, psub)
    q.add_argument("population", metavar="NAME", help="a built-in population name, a manifest file or a population folder")
    q = command(
        "train",
        "train a self-play population from a YAML (see tune_configs/selfplay_*.yaml)",
        commands.partners_train,
        psub,
        epilog=keys_help(SelfPlayConfig, GENERATOR_KEYS, "partner generators (YAML keys, or --set KEY=VALUE):"),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    q.add_argument("config", help="self-play YAML (see tune_configs/selfplay_*.yaml)")
    q.add_argument("--out", default="populations", help="folder for the population (default: populations)")
    q.add_argument("--overwrite", action="store_true", help="replace an existing population of the same name")
    run_args(q), log_arg(q)
    q = command(
        "from-set",
        "write an evaluation set's partners as a population to train with (a trained best response bounds the set)",
        commands.partners_from_set,
        psub,
    )
    q.add_argument("set", metavar="SET", help="an evaluation-set manifest file, or a shipped set (e.g. overcooked_heldout)")
    q.add_argument("--name", help="the population's name (default: <set name>-partners)")
    q.add_argument("--out", default="populations", help="folder for the population (default: populations)")
    q.add_argument("--overwrite", action="store_true", help="replace an existing population of the same name")
    q = command(
        "prune",
        "keep a self-play population's most diverse training pairs by their event profiles (HSP's pool pruning)",
        commands.partners_prune,
        psub,
    )
    q.add_argument("population", metavar="NAME", help="a population folder or manifest (its training pairs need counterparts)")
    q.add_argument("--keep", type=positive_int, required=True, help="training pairs to keep (test members are all kept)")
    q.add_argument("--episodes", type=positive_int, default=10, help="episodes per pair for its event profile (default: 10)")
    q.add_argument("--seed", type=int, default=0, help="seed of the profiling episodes (default: 0)")
    q.add_argument("--name", help="the pruned population's name (default: <name>-pruned<keep>)")
    q.add_argument("--out", default="populations", help="folder for the population (default: populations)")
    q.add_argument("--overwrite", action="store_true", help="replace an existing population of the same name")


def _adapt(command: Callable[..., argparse.ArgumentParser]) -> None:
    d = lambda key: described(AdaptConfig, key)  # noqa: E731
    p = command(
        "adapt",
        "adapt trained egos to new partners (fresh head, task module kept, lam 0)",
        commands.adapt,
        epilog=set_help(AdaptConfig, ADAPT_OPTIONS),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    runs_args(p, "adaptation", " and Tune experiment")
    p.add_argument("--partner", action="append", help=d("partners") + " (repeatable)")
    p.add_argument("--population", help=d("population"))
    p.add_argument("--split", default="test", choices=["train", "test"], help=d("split"))
    p.add_argument("--method", choices=["scratch"], help=d("method"))
    p.add_argument("--frozen-task", action="store_true", help="keep the task module frozen while adapting (train_task: false)")
    p.add_argument("--head-init", default="fresh", choices=["fresh", "pick", "posterior", "plastic"], help=d("head_init"))
    p.add_argument("--pick-steps", type=positive_int, help=d("pick_steps"))
    p.add_argument("--guard", action="store_true", help=d("guard"))
    run_args(p), log_arg(p)


def _zeroshot(command: Callable[..., argparse.ArgumentParser]) -> None:
    p = command(
        "zeroshot",
        "zero-shot coordination on the new task with known partners",
        commands.zeroshot,
        epilog=set_help(ZeroShotConfig, ZEROSHOT_OPTIONS),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    runs_args(p, "zeroshot", " and Tune experiment")
    p.add_argument(
        "--new-task",
        action="store_true",
        help="the new task is each run's population's -newtask variant (what happens without --new-population)",
    )
    p.add_argument("--new-population", help=described(ZeroShotConfig, "new_population"))
    run_args(p), log_arg(p)


def _players(command: Callable[..., argparse.ArgumentParser]) -> None:
    p = command("marginals", "distance of each run's task module to the true marginals", commands.marginals)
    runs_args(p, "marginals", "")
    p.add_argument(
        "--episodes",
        type=positive_int,
        default=200,
        help="episodes per training partner to collect states (non-bandit games; default 200)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of those episodes (default 0)")
    p = command(
        "pair",
        "play fixed players together, one per seat (ego heads, task modules, population members, scripted partners)",
        commands.pair,
        description="Play fixed players, one per seat, for N episodes; write their mean return, its standard error "
        "and, on the bandit, the exact expected return to a CSV.",
        epilog=SEAT_SYNTAX,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("seats", nargs="+", metavar="SEAT", help=described(PairConfig, "seats") + " (syntax below)")
    p.add_argument(
        "--episodes",
        type=positive_int,
        default=PairConfig.model_fields["episodes"].default,
        help=described(PairConfig, "episodes"),
    )
    p.add_argument("--seed", type=int, default=PairConfig.model_fields["seed"].default, help=described(PairConfig, "seed"))
    p.add_argument("--env", help=described(PairConfig, "env"))
    p.add_argument("--env-config", metavar="YAML", help=described(PairConfig, "env_config"))
    p.add_argument("--name", help="name of the output CSV (default: after the seats)")
    p.add_argument("--out", default="pair", help="folder for the CSV (default: pair)")
    p = command("crossplay", "pair every member of population A (ego seat) with every member of B", commands.crossplay)
    p.add_argument("a", metavar="A", help="population name, manifest or folder (the ego seat)")
    p.add_argument("b", metavar="B", help="population name, manifest or folder (the partner seat)")
    p.add_argument("--episodes", type=positive_int, default=100, help="episodes per pair (default 100)")
    p.add_argument("--seed", type=int, default=0, help="seed of the episodes (default 0)")
    p.add_argument("--out", default="crossplay", help="folder for the CSV and PNG (default: crossplay)")


def _evaluate(command: Callable[..., argparse.ArgumentParser]) -> None:
    d = lambda key: described(EvaluateConfig, key)  # noqa: E731
    p = command(
        "evaluate",
        "score trained egos against a held-out or validation set, normalised by each partner's best-response bound",
        commands.evaluate,
        description="Score trained egos against an evaluation set (docs/protocol.md): per ego and partner the return "
        "(exact on the bandit and blocks), the partner's best-response bound and return / bound; per agent (one RUNS "
        "argument, its egos the seeds) the mean and IQM of those scores with bootstrap intervals over seeds. Writes "
        "OUT/NAME/scores.csv, summary.json and summary.png.",
    )
    p.add_argument("runs", nargs="+", metavar="RUNS", help=d("runs"))
    p.add_argument("--eval-set", default=EvaluateConfig.model_fields["eval_set"].default, metavar="SET", help=d("eval_set"))
    p.add_argument("--module", help=d("module"))
    p.add_argument("--episodes", type=positive_int, default=EvaluateConfig.model_fields["episodes"].default, help=d("episodes"))
    p.add_argument("--seed", type=int, default=EvaluateConfig.model_fields["seed"].default, help=d("seed"))
    p.add_argument(
        "--resamples", type=positive_int, default=EvaluateConfig.model_fields["resamples"].default, help=d("resamples")
    )
    p.add_argument("--confidence", type=float, default=EvaluateConfig.model_fields["confidence"].default, help=d("confidence"))
    p.add_argument("--name", help="name of the output folder (default: after RUNS, the set and the options that differ)")
    p.add_argument("--out", default="evaluation", help="folder for the output folder (default: evaluation)")


def _reproduce(command: Callable[..., argparse.ArgumentParser]) -> None:
    p = command("reproduce", "run every stage of the paper's experiments for a game (resumable)", commands.reproduce)
    p.add_argument(
        "game", help="the game whose experiments to run (bandit, blocks, hanabi, or all three); with --plan any registered game"
    )
    p.add_argument(
        "--seeds", type=positive_int, default=None, help="seeds per method (default: the seeds the plan declares, else 3)"
    )
    p.add_argument("--quick", action="store_true", help="a small version (1 seed, short runs) for demos and tests")
    p.add_argument("--out", default="reproduce", help="output folder (default: reproduce)")
    p.add_argument("--populations", nargs="+", metavar="NAME", help="only these populations (e.g. bandit-s2-hand bandit-s1-hand)")
    p.add_argument(
        "--methods", nargs="+", metavar="LABEL", help="only these methods (e.g. agg maml; modular-lam0.5 is always run)"
    )
    p.add_argument(
        "--redo",
        choices=["adapt", "zeroshot", "marginals", "heldout", "evaluate"],
        help="run this finished stage again for the plan's experiments; their old outputs move to <out>/<game>/superseded/",
    )
    p.add_argument(
        "--train-steps",
        type=positive_int,
        default=None,
        metavar="N",
        help="env steps each ego trains for (default: the paper's, per game); a folder trained with another budget is refused",
    )
    p.add_argument(
        "--plan",
        default=None,
        metavar="FILE",
        help="a plan YAML to run instead of the shipped tune_configs/plan_GAME.yaml (copy and edit that file)",
    )
    p.add_argument("--address", default=None, help="Ray cluster address; default: $RAY_ADDRESS or a local Ray")
    log_arg(p)
    p = command("report", "build report.md (the paper's numbers beside ours, figures) from a reproduce folder", commands.report)
    p.add_argument("root", metavar="ROOT", help="a `reproduce --out` folder (one sub-folder per game) or one game folder")
    p.add_argument("--out", default=None, help="folder for report.md and figures/ (default: ROOT/report)")
    p.add_argument(
        "--user-study",
        nargs="*",
        default=None,
        metavar="PATH",
        help="recorded session CSVs or folders (default: ROOT/user_study)",
    )
    p = command(
        "plot", "draw (again) the figures of a training or sweep folder, or of adaptation or zero-shot CSVs", commands.plot
    )
    p.add_argument(
        "folder",
        metavar="FOLDER",
        help="a training or sweep folder (STORAGE/NAME), an adaptation or zero-shot CSV, or a folder of them",
    )


def _play(sub: Any) -> None:
    from rllib_conv.play import command as play_command  # stdlib-only: the server loads when `play` runs

    p = sub.add_parser(
        "play",
        help="web page: people play the bandit study or blocks with the trained ego or each other",
        description=play_command.DESCRIPTION,
    )
    play_command.add_arguments(p)
    p.add_argument("-v", dest="verbose", action="store_true", help="same as --verbose; also shows Ray's and Tune's warnings")
    p.set_defaults(func=commands.play)


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of every subcommand."""
    verbosity = Parser(add_help=False)
    verbosity.add_argument(
        "-v", "--verbose", action="store_true", help="show Ray's and Tune's own messages and warnings (hidden by default)"
    )
    parser = Parser(prog="rllib-conv", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"rllib-conv {_version()}", help="print the version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(
        name: str, help: str, func: Callable[[argparse.Namespace], None], group: Any = sub, **kwargs: Any
    ) -> argparse.ArgumentParser:
        p = group.add_parser(name, help=help, description=kwargs.pop("description", help), parents=[verbosity], **kwargs)
        p.set_defaults(func=func)
        return p

    _train(command)
    _partners(sub, command)
    _adapt(command)
    _zeroshot(command)
    _players(command)
    _evaluate(command)
    _reproduce(command)
    human_data_parsers(command)
    _play(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit status (0 ok, 1 a failed run, 2 bad input, 130 interrupted)."""
    args = build_parser().parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the exact command, for outputs that record it
    try:
        with commands.quiet(args.verbose, keep_logs=args.command == "play"):
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
