"""The `rllib-conv play` subcommand: its arguments and what it runs.

Kept free of heavy imports (torch, Ray) so that building the CLI parser stays fast; the
server and the trained egos load only when the command runs.
"""

from __future__ import annotations

import argparse

DESCRIPTION = """\
Serve a page on 127.0.0.1 where people play the bandit of the paper's user study (or the
blocks game), with the trained ego in RUN or with each other (two browsers, one room code).
The bandit session is the study's: Train task then Test task, contexts A, B, C, 5 tries
each, both picks revealed after every try. The agent plays its task module's marginals
times a partner module for this person, updated after every try by one cross-entropy
step toward the person's arm (step --step-size; see rllib_conv/play/agent.py). On the
Test task its prior is the task module of --test-run (an ego trained on the Test task,
e.g. population bandit-user-study-newtask); without it, --test-prior: "oracle" (default,
the Test task's true marginals: uniform over the good arms the person sees) or
"uniform" (uniform over the 4 arms). Bandit sessions are recorded in OUT/bandit_*.csv
in the format of analysis/data/user_study.csv; blocks in OUT/blocks/*.csv; one line per
session in OUT/sessions.jsonl.
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the `play` arguments to `p`."""
    p.add_argument("run", nargs="?", default=None, help="trained-ego trial folder (bandit: trained on the user-study Train task); without it only two-person rooms")
    p.add_argument("--game", choices=["bandit", "blocks"], default=None, help="the game (default: RUN's game, else bandit)")
    p.add_argument("--port", type=int, default=8000, help="port on 127.0.0.1 (default 8000; 0 picks a free one)")
    p.add_argument("--test-run", default=None, help="bandit: ego trained on the Test task, the agent's prior there")
    p.add_argument(
        "--test-prior",
        choices=["oracle", "uniform"],
        default="oracle",
        help="bandit, without --test-run: the agent's Test-task prior: the true marginals (oracle, default) or uniform over arms",
    )
    p.add_argument("--out", default="play_sessions", help="folder for the recordings (default: play_sessions)")
    p.add_argument("--step-size", type=float, default=3.0, help="the agent's adaptation step size eta (default 3: one observed pick -> 0.95)")
    p.add_argument("--greedy", action="store_true", help="the agent plays its most likely action instead of sampling")
    p.add_argument("--games", type=int, default=5, help="blocks: games per session (default 5)")
    p.add_argument("--seed", type=int, default=0, help="seed of the agent's choices and the blocks goals")
    p.add_argument("--verbose", action="store_true", help="log every HTTP request")


def run(args: argparse.Namespace) -> None:
    """Build the lobby from `args` and serve until Ctrl-C (ValueError for bad arguments)."""
    from rllib_conv.play.server import build_lobby, serve

    lobby = build_lobby(
        args.run,
        game=args.game,
        test_run=args.test_run,
        test_prior=args.test_prior,
        out=args.out,
        step_size=args.step_size,
        greedy=args.greedy,
        seed=args.seed,
        games=args.games,
    )
    serve(lobby, port=args.port, verbose=args.verbose)
