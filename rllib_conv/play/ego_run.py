"""A trained ego for the web app: read from its trial folder, with its task module as the agent's prior (`agent.py`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rllib_conv import envs, partners
from rllib_conv.adaptation.convention_posterior import known_conventions
from rllib_conv.common.methods import method
from rllib_conv.common.run_folders import CONFIG_FILE, experiment_of, trial_folders, trial_name
from rllib_conv.envs.convention_keys import convention_key
from rllib_conv.modules.multi import AGG_HEAD_ID
from rllib_conv.partners.population import Population
from rllib_conv.play.agent import Prior, legal_renormalised
from rllib_conv.play.convention_agent import ConventionSource
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import head_probs, load_module, task_probs
from rllib_conv.training.experiment import ExperimentConfig, trial_config


def module_prior(module: Any, head_id: str | None = None) -> Prior:
    """The task module's action distribution of a trained ego (`head_id`: a single-network method's head)."""

    def prior(obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        mask = np.asarray(mask, dtype=np.float32)
        probs = task_probs(module, obs, mask) if head_id is None else head_probs(module, head_id, obs, mask)
        return legal_renormalised(probs, mask)

    return prior


@dataclass
class EgoRun:
    """A trained ego read from its trial folder: config, population, seat and task-module prior."""

    trial: Path
    exp: ExperimentConfig
    population: Population
    prior: Prior = field(repr=False)

    @property
    def game(self) -> str:
        """The game the ego was trained on ("bandit", "blocks", ...)."""
        return self.population.env

    @property
    def env_config(self) -> dict[str, Any]:
        """The env config of the ego's training task (the population's)."""
        return dict(self.population.env_config)

    @property
    def ego_seat(self) -> int:
        """The seat (1 = player_0, 2 = player_1) the ego was trained in."""
        return 2 if self.population.partner_agent == "player_0" else 1

    def describe(self) -> str:
        """One line for people: method, lam, population, folder."""
        return f"{self.exp.method} ego (lam {self.exp.lam:g}) trained with {self.population.name}, {experiment_of(self.trial).name}/{trial_name(self.trial)}"


def load_run(path: str | Path, what: str = "RUN") -> EgoRun:
    """Read a trained-ego trial folder (or an experiment folder holding exactly one trial).

    Raises ValueError naming `what` (the argument) if the folder is not a trained ego with a
    checkpoint, holds several trials, or its method has no marginal estimate to use as prior.
    """
    path = Path(path)
    if not path.exists():
        raise ValueError(
            f"{what} {str(path)!r} does not exist; expected a trained-ego trial folder (with {CONFIG_FILE} and checkpoint_*/)"
        )
    try:
        trials = trial_folders(path)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None
    if len(trials) != 1:
        names = ", ".join(t.name for t in trials[:3]) + (", ..." if len(trials) > 3 else "")
        raise ValueError(f"{what} {str(path)!r} holds {len(trials)} trained-ego trials ({names}); pass one trial folder")
    trial = trials[0]
    exp = trial_config(trial)
    prior = method(exp.method).prior
    if prior is None:
        raise ValueError(
            f"{what} {str(trial)!r} is a {exp.method!r} ego: its task module is not a marginal estimate; use a modular run"
        )
    try:
        checkpoint = last_checkpoint(trial)
    except ValueError as exc:
        raise ValueError(f"{what}: {exc}") from None
    module = load_module(checkpoint)
    head = AGG_HEAD_ID if prior == "network" else None
    return EgoRun(trial=trial, exp=exp, population=partners.get(exp.population), prior=module_prior(module, head))


def convention_source(run: EgoRun, what: str) -> ConventionSource:
    """The training partners, the trained ego's head for each, the game's key and planner, for `--adapter posterior`; ValueError naming `what` if the run has no per-partner heads."""
    if method(run.exp.method).single_head:
        raise ValueError(
            f"--adapter posterior: {what} {str(run.trial)!r} is a {run.exp.method!r} ego with one shared head; it needs one head per training partner (a modular run)"
        )
    known = known_conventions(run.population, load_module(last_checkpoint(run.trial)), f"--adapter posterior: {what}")
    ego_agent = "player_0" if run.ego_seat == 1 else "player_1"
    planner = envs.best_response(run.game, run.env_config, ego_agent)
    return ConventionSource(models=known.models, known=known.heads, key=convention_key(run.game), planner=planner)


def require_user_study(run: EgoRun, new_task: bool, what: str) -> None:
    """Raise ValueError unless `run` was trained on the user-study bandit's Train (or, `new_task`, Test) task."""
    cfg = run.env_config
    task = "Test" if new_task else "Train"
    if run.game != "bandit" or cfg.get("task") != "user_study" or bool(cfg.get("new_task", False)) != new_task:
        wanted = "bandit-user-study-newtask" if new_task else "bandit-user-study"
        raise ValueError(
            f"{what} {str(run.trial)!r} was trained on {run.game} with {cfg} (population {run.population.name!r}); "
            f"the study's {task} task needs an ego trained on the user-study bandit's {task} task (e.g. population {wanted})"
        )
