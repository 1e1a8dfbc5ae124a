"""`EvaluateConfig`: the schema of `rllib-conv evaluate`, and the checks that need no torch or Ray.

The command line validates once against the schema (its option help texts are the field
descriptions), then `check` reads every trained ego's config and the evaluation set:
an unknown set, a missing folder or an ego of another game, settings or seat is refused
in a second, before a network loads and before anything is written.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import Field, PositiveInt

from rllib_conv import envs
from rllib_conv.common.config_files import Strict
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.partners.evaluation_sets import EvaluationSet, find_set
from rllib_conv.partners.population import Population
from rllib_conv.pipelines.naming import run_label
from rllib_conv.pipelines.pair_config import MAX_EPISODES, trained_game
from rllib_conv.training.experiment import check_trial

MAX_RESAMPLES = 10**6  # beyond any interval's need, and within a bootstrap's memory


class EvaluateConfig(Strict):
    """Trained egos against one evaluation set: returns, best-response bounds, normalised scores and their aggregates."""

    runs: list[str] = Field(
        min_length=1,
        description="trained-ego folders (.../seed=<s>/) or trial or experiment folders holding several; "
        "each argument is one agent, its egos the seeds",
    )
    eval_set: str = Field(
        "heldout",
        min_length=1,
        description="the partners: heldout or validation (the shipped set of the egos' game) or an evaluation-set manifest file",
    )
    module: str | None = Field(
        None,
        description="the module of each ego that plays: ego (the one head of agg, maml, ...), task (the task module alone) "
        "or ego@NAME (default: the one head, else the task module)",
    )
    episodes: PositiveInt = Field(
        64, le=MAX_EPISODES, description="sampled episodes per (ego, partner) where the game has no exact return"
    )
    seed: int = Field(0, description="seed of the sampled episodes and of the egos' sampling")
    resamples: PositiveInt = Field(9999, le=MAX_RESAMPLES, description="bootstrap resamples of the seeds")
    confidence: float = Field(0.95, gt=0, lt=1, description="confidence level of the bootstrap intervals")


@dataclass(frozen=True)
class TrainedEgo:
    """One trained ego to evaluate: the agent (RUNS argument) it belongs to, its folder and its training seed."""

    agent: str
    trial: Path
    seed: int


@dataclass(frozen=True)
class Evaluation:
    """What `check` found: the egos, the set as given and resolved, and the game they all play."""

    egos: list[TrainedEgo]
    eval_set: EvaluationSet
    partners: Population
    env: str
    env_config: dict[str, Any]


def same_settings(env: str, a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Whether two settings of `env` make the same game (a key left out is the env's default)."""
    defaults = {
        name: p.default
        for name, p in inspect.signature(envs.game(env).env).parameters.items()
        if p.default is not inspect.Parameter.empty
    }
    return {**defaults, **a} == {**defaults, **b}


def check(cfg: EvaluateConfig) -> Evaluation:
    """The egos of `cfg.runs` and the set they meet, checked to fit one another; ValueError naming the folder or the set."""
    egos, games = [], []
    for run in cfg.runs:
        if not Path(run).exists():
            raise ValueError(f"RUNS {run!r} does not exist")
        for trial in trial_folders(run):
            exp = check_trial(trial)
            egos.append(TrainedEgo(run_label(run), trial, exp.seed))
            games.append(trained_game(exp))
    env, env_config, partner_agent = games[0]
    for ego, (other, other_config, _) in zip(egos, games):
        if other != env or not same_settings(env, other_config, env_config):
            raise ValueError(
                f"RUNS: the egos play different games ({str(egos[0].trial)!r}: {env} {env_config}; "
                f"{str(ego.trial)!r}: {other} {other_config}); evaluate one game at a time"
            )
    try:
        eval_set = find_set(cfg.eval_set, env)
        partners = eval_set.resolve()
    except ValueError as exc:
        raise ValueError(f"--eval-set {cfg.eval_set!r}: {exc}") from None
    where = f"--eval-set {cfg.eval_set!r}"
    for ego, (_, _, seat) in zip(egos, games):
        try:
            check_fit(eval_set, partners, env, env_config, seat)
        except ValueError as exc:
            raise ValueError(f"{where}: {exc} (the ego in {str(ego.trial)!r})") from None
    return Evaluation(egos, eval_set, partners, env, env_config)


def check_fit(eval_set: EvaluationSet, partners: Population, env: str, env_config: dict[str, Any], seat: str | list[str]) -> None:
    """ValueError unless egos trained on `env` `env_config` with partners in `seat`(s) can meet `eval_set` (resolved:
    `partners`), each of its partners (teams) with a best-response bound, exact or declared."""
    if eval_set.env != env or not same_settings(env, eval_set.env_config, env_config):
        raise ValueError(f"the set is for {eval_set.env} {eval_set.env_config}, the egos were trained on {env} {env_config}")
    seats = [seat] if isinstance(seat, str) else list(seat)
    if seats != partners.partner_agents:
        raise ValueError(
            f"the set's partners play seat(s) {partners.partner_agents}, the egos were trained with partners in {seats}"
        )
    exact = envs.game(env).best_response_return is not None and len(seats) == 1
    unbounded = [name for name, _ in partners.teams() if name not in eval_set.bounds]
    if not exact and unbounded:
        raise ValueError(
            f"game {env!r} has no exact best-response bound to normalise by (the bandit and blocks have one; "
            f"no game of more than two seats), and the set declares none (`bounds:`, with `bounds_by`) for {unbounded}"
        )
