"""`python -m analysis ROOT [--out OUT] [--user-study PATH ...]`: build the reproduction report (see `analysis.report`)."""

from __future__ import annotations

import argparse


def main(argv: list[str] | None = None) -> None:
    """Parse the command line, build the report and print its path."""
    parser = argparse.ArgumentParser(
        prog="python -m analysis", description="Build report.md (paper vs ours, with figures) from a reproduction folder."
    )
    parser.add_argument("root", help="a `rllib-conv reproduce --out` folder (one sub-folder per game) or a single game folder")
    parser.add_argument("--out", default=None, help="folder for report.md and figures/ (default: ROOT/report)")
    parser.add_argument(
        "--user-study",
        nargs="*",
        default=None,
        metavar="PATH",
        help="recorded session CSVs or folders (default: ROOT/user_study if present)",
    )
    args = parser.parse_args(argv)
    from analysis.report import build_report

    print(build_report(args.root, args.out, args.user_study))


if __name__ == "__main__":
    main()
