"""The `rllib-conv play` subcommand: its arguments and what it runs (serve a study, or export one).

Kept free of heavy imports (torch, Ray, the web stack) so that building the CLI parser
stays fast; the server and the trained egos load only when the command runs.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
from pathlib import Path
from typing import Iterator

from rllib_conv.common.adapters import FRESH, OLD_SPELLINGS, names

EXPORT = "export"
ADMIN_TOKEN_ENV = "RLLIB_CONV_ADMIN_TOKEN"
MIN_ADMIN_TOKEN = 8  # as app.MIN_ADMIN_TOKEN; repeated here to keep the parser free of the web stack
DEFAULT_ENROL_LIMIT = 20  # as app.DEFAULT_ENROL_LIMIT

DESCRIPTION = """\
Serve a study where people play the bandit of the paper's user study (or the blocks game)
with a trained ego (RUN, or each --agent NAME=RUN) or with each other. Participants open
the page (recruitment links add ?participant=ID, or PROLIFIC_PID / workerId), consent,
read the instructions, are assigned to the condition with the fewest participants
(--conditions, e.g. agent,human or ours,baseline,human), play, and get a completion code.
Human pairs are formed automatically from participants waiting at the same time. The
bandit session is the study's: Train task then Test task, contexts A, B, C, 5 tries each.
The agent plays its task module's marginals times a partner module for this person,
updated after every try by one cross-entropy step toward the person's arm (--step-size;
see rllib_conv/play/agent.py); on the Test task its prior is the task module of
--test-run, or --test-prior. Every try is committed to OUT/study.sqlite3 (SQLite) before
it is acknowledged; restart on the same folder and participants resume. The admin page
(its token printed at start, unless it came from $RLLIB_CONV_ADMIN_TOKEN) shows live counts
per condition and downloads the export.

`rllib-conv play export DB [--out FILE] [--condition NAME]` writes the tries of study
database DB (or its folder) as a user-study CSV that `rllib-conv report --user-study` reads.
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the `play` arguments to `p`."""
    p.add_argument(
        "run",
        nargs="?",
        default=None,
        help="trained-ego trial folder: the agent named 'agent' (bandit: trained on the user-study Train task); or 'export'",
    )
    # Its own destination: sharing `--db`'s would let an absent positional overwrite `--db FILE`.
    p.add_argument(
        "export_db",
        nargs="?",
        default=None,
        metavar="db",
        help="with 'export': the study database (or the study folder holding study.sqlite3)",
    )
    p.add_argument(
        "--agent",
        action="append",
        default=[],
        metavar="NAME=RUN",
        help="an agent condition NAME playing the ego in RUN ('oracle': the bandit's true marginals, to pilot without training); repeatable",
    )
    p.add_argument(
        "--conditions",
        default=None,
        help="comma-separated conditions participants are assigned to, balanced: agent names and/or 'human' (default: every agent, or human without any)",
    )
    p.add_argument("--game", choices=["bandit", "blocks"], default=None, help="the game (default: the agents' game, else bandit)")
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (default 127.0.0.1; 0.0.0.0 for every interface, e.g. behind an HTTPS proxy)",
    )
    p.add_argument("--port", type=int, default=8000, help="port (default 8000; 0 picks a free one)")
    p.add_argument(
        "--test-run",
        action="append",
        default=[],
        metavar="[NAME=]RUN2",
        help="bandit: ego trained on the Test task, agent NAME's prior there (no NAME: the agent 'agent'); repeatable",
    )
    p.add_argument(
        "--test-prior",
        choices=["oracle", "uniform"],
        default="oracle",
        help="bandit, agents without --test-run: the Test-task prior: the true marginals (oracle, default) or uniform over arms",
    )
    p.add_argument(
        "--out",
        default=None,
        help="the study folder (default: play_sessions); with 'export': the CSV file to write (default: user_study.csv beside DB)",
    )
    p.add_argument("--db", default=None, help="the study database (default: OUT/study.sqlite3)")
    p.add_argument("--condition", default=None, help="with 'export': only this condition's tries")
    p.add_argument(
        "--seat",
        type=int,
        choices=[1, 2],
        default=None,
        help="the person's seat in agent conditions (default: opposite the trained ego)",
    )
    p.add_argument(
        "--step-size", type=float, default=3.0, help="the agent's adaptation step size eta (default 3: one observed pick -> 0.95)"
    )
    p.add_argument("--greedy", action="store_true", help="the agent plays its most likely action instead of sampling")
    p.add_argument(
        "--adapter",
        choices=[*names(role="start", surface="play"), *OLD_SPELLINGS],
        default=FRESH,
        help="how agents adapt between tries: fresh (the paper's partner module, learnt from the person; default; 'table' is its old spelling) or posterior: also by a posterior over "
        "which training partner's convention the person follows: that partner's head (bandit) or the best response to it (blocks, agent as P1); not in the paper",
    )
    p.add_argument("--games", type=int, default=5, help="blocks: games per session (default 5)")
    p.add_argument(
        "--seed", type=int, default=0, help="seed of the assignment's tie-breaks, the agent's choices and the blocks goals"
    )
    p.add_argument(
        "--pair-timeout",
        type=float,
        default=300.0,
        help="seconds a participant of the human condition waits for a partner (default 300)",
    )
    p.add_argument(
        "--idle-timeout", type=float, default=600.0, help="seconds without a move before a session ends early (default 600)"
    )
    p.add_argument(
        "--completion-code",
        default=None,
        help="the code shown at the end, as the recruitment platform expects (default: a random code per participant)",
    )
    p.add_argument(
        "--consent",
        default=None,
        metavar="FILE",
        help="text file with the consent form shown first (paragraphs separated by blank lines)",
    )
    p.add_argument(
        "--admin-token",
        default=None,
        help=f"the admin page's token, at least {MIN_ADMIN_TOKEN} characters (default: ${ADMIN_TOKEN_ENV}, never printed; else a random one, printed at start)",
    )
    p.add_argument(
        "--enrol-limit",
        type=int,
        default=DEFAULT_ENROL_LIMIT,
        metavar="N",
        help=f"at most N enrolments (and re-enrolment attempts) per client address per minute; more get 429 (default {DEFAULT_ENROL_LIMIT}; 0: no limit)",
    )
    p.add_argument("--verbose", action="store_true", help="log every HTTP request")


def run(args: argparse.Namespace) -> None:
    """Serve the study described by `args` until Ctrl-C, or export one (ValueError for bad arguments).

    Every argument is checked before anything is written: a refused command leaves the
    study folder as it was.
    """
    if args.run == EXPORT:
        return _export(args)
    if args.export_db is not None:
        raise ValueError(
            f"unexpected argument {args.export_db!r} after RUN (only `play export DB` takes a second one; the study database is --db FILE)"
        )
    if args.condition is not None:
        raise ValueError("--condition is for `play export DB`; to serve, use --conditions")
    token_from_env = not args.admin_token and bool(os.environ.get(ADMIN_TOKEN_ENV))
    token = args.admin_token or os.environ.get(ADMIN_TOKEN_ENV) or None
    if token is not None and len(token) < MIN_ADMIN_TOKEN:
        where = f"${ADMIN_TOKEN_ENV}" if token_from_env else "--admin-token"
        raise ValueError(f"{where} must be at least {MIN_ADMIN_TOKEN} characters")
    if args.enrol_limit < 0:
        raise ValueError(f"--enrol-limit must be 0 (no limit) or more, got {args.enrol_limit}")
    from rllib_conv.play.conditions import DEFAULT_CONSENT, build_settings
    from rllib_conv.play.server import StudyServer
    from rllib_conv.play.store import DB_FILE

    consent = DEFAULT_CONSENT
    if args.consent is not None:
        try:
            consent = Path(args.consent).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise ValueError(f"--consent {args.consent!r}: cannot read it as UTF-8 text ({exc})") from None
    out = Path(args.out or "play_sessions")
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {str(out)!r} is a file; expected the study folder")
    with _quiet_loading(args.verbose):
        settings = build_settings(
            args.run,
            agents=args.agent,
            conditions=args.conditions,
            game=args.game,
            test_runs=args.test_run,
            test_prior=args.test_prior,
            step_size=args.step_size,
            greedy=args.greedy,
            seed=args.seed,
            adapter=args.adapter,
            games=args.games,
            person_seat=args.seat,
            pair_timeout=args.pair_timeout,
            idle_timeout=args.idle_timeout,
            completion_code=args.completion_code,
            consent=consent,
        )
    db = Path(args.db) if args.db else out / DB_FILE
    server = StudyServer(
        settings, db, host=args.host, port=args.port, admin_token=token, verbose=args.verbose, enrol_limit=args.enrol_limit
    )
    conditions = ", ".join(c.name for c in settings.conditions)
    print(f"rllib-conv play: {settings.game} study, conditions {conditions}; database {db}", flush=True)
    if token_from_env:  # a token kept out of the command line stays out of console logs too
        print(f"admin page: {server.url}admin (token: ${ADMIN_TOKEN_ENV})", flush=True)
    else:
        print(f"admin page: {server.admin_url}", flush=True)
    print(f"participants: {server.url}?participant=ID (or no id: one is generated)", flush=True)
    print(f"open {server.url} in a browser (Ctrl-C stops)", flush=True)
    server.run()


@contextlib.contextmanager
def _quiet_loading(verbose: bool) -> Iterator[None]:
    """Drop log records up to WARNING while the egos load, unless `verbose`.

    RLlib logs a DeprecationWarning of its own API when it rebuilds a module from a
    checkpoint; a study's operator can do nothing about it. The server's own warnings
    come later and are kept.
    """
    if verbose:
        yield
        return
    logging.disable(logging.WARNING)
    try:
        yield
    finally:
        logging.disable(logging.NOTSET)


def _export(args: argparse.Namespace) -> None:
    if args.export_db is not None and args.db is not None and args.export_db != args.db:
        raise ValueError(f"play export: DB {args.export_db!r} and --db {args.db!r} differ; give the database once")
    db = args.export_db or args.db
    if db is None:
        raise ValueError("play export needs DB: the study database (or the study folder holding study.sqlite3)")
    from rllib_conv.play.export import export

    path, rows = export(db, args.out, args.condition)
    print(f"wrote {rows} rows to {path}")
