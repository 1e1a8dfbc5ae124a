"""A game's record: everything one game contributes to the house, in one typed value.

A game is one folder (`envs/bandit/`, `envs/blocks/`, `envs/hanabi/`: its env, oracle,
convention key, best response and `record.py`) plus one `GameRecord`, registered with
`registry.register_game`. Every layer asks the record instead of branching on a game's
name: training reads its defaults, the marginals its oracle, the adapters its convention
key and best response, `reproduce` its plan and whether it has a new task, and the report
its maximum score and title (written by the run into plan.json: the analysis reads files).

A game outside the package (a test's, a user's) is a module holding its record, named by
import path (`"package.module:RECORD"`); every process, Ray workers included, imports it on
first use.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pettingzoo.utils.env import AECEnv, ParallelEnv

from rllib_conv.envs.defaults import FALLBACK_DEFAULTS, AdaptDefaults, TrainingDefaults, ZeroShotDefaults

EnvFactory = Callable[..., AECEnv | ParallelEnv]
# Observations [B, obs_dim] -> 0/1 mask [B, num_actions] of the actions optimal whatever the partner's convention.
OracleFn = Callable[[np.ndarray], np.ndarray]
OracleBuilder = Callable[..., OracleFn]  # (**env_config) -> OracleFn
# Observations [B, obs_dim] -> [B, num_actions] canonical action of each action (same effect, same index).
CanonicalFn = Callable[[np.ndarray], np.ndarray]
# env_config -> every state of the ego (observations [S, obs_dim], masks [S, num_actions]).
StatesFn = Callable[[dict[str, Any]], tuple[np.ndarray, np.ndarray]]
KeyFn = Callable[[np.ndarray], int]  # an observation -> the situation it is (see `convention_keys`)
# (env_config, ego_agent) -> a `best_response.BestResponse`, or None for seats it cannot plan for.
BestResponseFactory = Callable[[dict[str, Any], str], Any]
# ({agent: policy with action_probs}, env_config) -> the exact expected score, or None where it cannot be known.
ExactReturnFn = Callable[[dict[str, Any], dict[str, Any]], float | None]
# (partner policy with action_probs, env_config, ego_agent) -> the expected score of the ego's best response to that
# partner, exact, or None where it cannot be known (a partner that does not say what it draws from, a seat not planned).
BestResponseReturnFn = Callable[[Any, dict[str, Any], str], float | None]
# (env_config, ego_agent, agent) -> what seat `agent` observes and may do, as the ego's own observation shows it
# (`seat_views.SeatView`), or None where the ego's observation does not show it (a partial view).
SeatViewFactory = Callable[[dict[str, Any], str, str], Any]


@dataclass(frozen=True)
class GameRecord:
    """One game: its env and what every stage needs to know of it (None: the game has none)."""

    name: str  # what configs, populations and the CLI call it
    env: EnvFactory  # `env(**env_config)` -> a PettingZoo env (AEC or parallel)
    title: str = ""  # the report's name for it
    training: TrainingDefaults | None = None  # None: `FALLBACK_DEFAULTS`
    adaptation: AdaptDefaults | None = None  # None: derived from the ego's rollout (`adapt_defaults`)
    zeroshot: ZeroShotDefaults | None = None  # None: derived from the ego's rollout and budget
    new_task: bool = False  # `env(new_task=True)` is a new task with the same partners: zero-shot applies
    oracle: OracleBuilder | None = None  # optimal actions: the `oracle` method and the marginals need one
    canonical: CanonicalFn | None = None  # which actions are one move; None: every action its own
    states: StatesFn | None = None  # the ego's every state, where a game can list them; None: the marginals sample play
    convention_key: KeyFn | None = None  # None: each move is its own situation
    best_response: BestResponseFactory | None = None  # None: the ego cannot plan against a partner model
    exact_return: ExactReturnFn | None = None  # None: scores come from sampled episodes only
    # The best response's expected score against a given partner: `evaluate` normalises returns by it. None:
    # no exact bound is known (`evaluate` refuses the game).
    best_response_return: BestResponseReturnFn | None = None
    # What a partner's observation shows that the ego's seat never observes (Hanabi: the ego's own hand). None:
    # the partner sees nothing the ego cannot know from its own observations and moves, so an adapter may read
    # the partner's moves in the situation the partner saw (`adaptation.registry.check_information`).
    partner_sees: str | None = None
    # Another seat's observation and legal moves rebuilt from the ego's own observation (and move) by the game's rules
    # (`seat_views`): an adapter that models the partners' moves reads them in that situation, on equal information.
    # None: the game cannot (adapters that need it are refused).
    seat_view: SeatViewFactory | None = None
    max_score: float | None = None  # the best score an episode can reach (report tables)
    # Env settings every measured score uses, over the training ones (`registry.make_scored`): Overcooked
    # trains on a shaped reward but is scored on soups delivered alone, as Carroll et al. report it.
    scoring: dict[str, Any] = field(default_factory=dict)
    # The events a seat's reward can weight instead of the game's (the env's `hidden_utility` option, {seat: {event:
    # weight}}): hidden-utility self-play (HSP) draws its biased partners' weights over them. (): the game has none.
    events: tuple[str, ...] = ()
    # Import paths of the modules that register its scripted partner kinds and built-in
    # populations: they sit in the partners layer, above this one, so the record names them
    # and `rllib_conv.partners` imports them.
    partners: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"game name must be a non-empty string, got {self.name!r}")
        if not callable(self.env):
            raise ValueError(f"game {self.name!r}: env must be callable (env_config -> PettingZoo env), got {self.env!r}")

    def training_defaults(self) -> TrainingDefaults:
        """The paper's network size, PPO batches and budget for this game (the fallback for a game without)."""
        return self.training or FALLBACK_DEFAULTS

    def adapt_defaults(self, rollout_per_partner: int) -> AdaptDefaults:
        """The adaptation protocol; a game without one evaluates every rollout, for 20 rollouts, with the ego's PPO batches."""
        return self.adaptation or AdaptDefaults(every=rollout_per_partner, steps=20 * rollout_per_partner)

    def zeroshot_defaults(self, rollout_per_partner: int, timesteps: int) -> ZeroShotDefaults:
        """The zero-shot budgets; a game without them trains heads for 10 rollouts and the task module for the ego's budget."""
        return self.zeroshot or ZeroShotDefaults(head_steps=10 * rollout_per_partner, task_steps=timesteps)

    def report_facts(self) -> dict[str, Any]:
        """What the report needs of this game, as a run writes it beside its results (the analysis reads files only)."""
        return {"title": self.title or self.name, "max_score": self.max_score}
