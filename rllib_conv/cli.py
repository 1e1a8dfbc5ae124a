"""`rllib-conv`: the command line. Each subcommand parses arguments and calls one pipeline.

Bad input (an unknown env, population or config key, a missing file) prints one
`rllib-conv: error: ...` line and exits with status 2, before anything is written.
"""

from __future__ import annotations

import argparse
import sys
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
    import pandas as pd

    from rllib_conv.pipelines.scripted_demo import demo_table

    print("Scripted partners against scripted egos that know each convention (mean score per episode):")
    table = demo_table(num_episodes=args.episodes, seed=args.seed)
    with pd.option_context("display.width", 200, "display.float_format", "{:.3f}".format):
        print(table.to_string(index=False))


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of every subcommand."""
    parser = argparse.ArgumentParser(prog="rllib-conv", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("demo", help="short end-to-end demo")
    p.add_argument("--episodes", type=int, default=100, help="episodes per pair of players (default 100)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=_cmd_demo)

    p = sub.add_parser("envs", help="list the registered games")
    p.set_defaults(func=_cmd_envs)

    p = sub.add_parser("partners", help="partner populations")
    psub = p.add_subparsers(dest="partners_command", required=True)
    pl = psub.add_parser("list", help="list the built-in populations")
    pl.set_defaults(func=_cmd_partners_list)
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
