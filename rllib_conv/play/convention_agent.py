"""The study agent adapting by the convention posterior (`--adapter posterior`; not in the paper).

Between a person's tries (bandit) or games (blocks) it updates
`adaptation.convention_posterior.ConventionPosterior` (which of its training partners'
conventions, whole or situation by situation, the person is following) from the person's
moves, and plays `PosteriorPlayer`'s answer. On the bandit that is the mixture of the
trained ego's head for a convention it has recognised and the paper's agent
(`agent.AdaptiveAgent`: task module times a partner table learnt from this person) where
none fits or a context is unseen. On blocks, with the agent in the trained ego's seat P1,
it plays the exact best response (`envs.best_response`) to the posterior's prediction of
the person's moves, re-planned after every game. On a task other than the one its ego was
trained on (the bandit's Test task) the heads do not apply, and it plays the paper's agent
alone, with the table carried over.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rllib_conv.adaptation.convention_posterior import ConventionPosterior, PosteriorPlayer
from rllib_conv.envs.best_response import BestResponse
from rllib_conv.envs.convention_keys import KeyFn
from rllib_conv.partners.base import Partner
from rllib_conv.play.agent import AdaptiveAgent, Prior, Target


class _TablePlayer(Partner):
    """The paper's agent as a `Partner`: what the posterior falls back to."""

    def __init__(self, agent: AdaptiveAgent) -> None:
        super().__init__("table")
        self.agent = agent

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return self.agent.act(observation, action_mask)

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        return np.stack([self.agent.policy(o, m) for o, m in zip(observations, action_masks)])

    def params(self) -> dict:
        return {}


class ConventionAgent:
    """`AdaptiveAgent`'s interface (`prior`, `policy`, `act`, `learn`, `watch`), adapting by the convention posterior on `home_prior`'s task.

    `known[k]` is the trained ego with head k (its answer to training partner k, whose model
    the posterior holds); `home_prior` the task module of the task those heads were trained
    on; `planner` the game's best response to a partner model, if it has one.
    """

    def __init__(
        self,
        table: AdaptiveAgent,
        posterior: ConventionPosterior,
        known: list[Partner],
        home_prior: Prior,
        seed: int | list[int] | None = None,
        planner: BestResponse | None = None,
    ) -> None:
        self.table, self.posterior, self.home_prior = table, posterior, home_prior
        self._known, self._planner = known, planner
        self._player = self._new_player()
        self._rng = np.random.default_rng(seed)

    def _new_player(self) -> PosteriorPlayer:
        # A player plans once, from the evidence it is built with (it reads `posterior` live otherwise).
        return PosteriorPlayer("agent", self.posterior, self._known, _TablePlayer(self.table), planner=self._planner)

    @property
    def prior(self) -> Prior:
        """The task module in use (the bandit room swaps it with the task)."""
        return self.table.prior

    @prior.setter
    def prior(self, prior: Prior) -> None:
        self.table.prior = prior

    def policy(self, obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The agent's action probabilities at one observation."""
        if self.table.prior is not self.home_prior:
            return self.table.policy(obs, mask)
        return self._player.action_probs(np.asarray(obs, dtype=np.float32)[None], np.asarray(mask)[None])[0]

    def act(self, obs: np.ndarray, mask: np.ndarray) -> int:
        """Sample (or, if the table agent is greedy, pick the best of) the agent's action."""
        probs = self.policy(obs, mask)
        if self.table.greedy:
            return int(self._rng.choice(np.flatnonzero(probs >= probs.max() - 1e-12)))
        return int(self._rng.choice(len(probs), p=probs / probs.sum()))

    def learn(self, targets: list[Target]) -> None:
        """The hindsight targets: into the partner table (the paper's agent inside)."""
        self.table.learn(targets)

    def watch(self, moves: list[Target]) -> None:
        """The person's moves (observation, mask, action): on the home task, into the posterior (and the plan)."""
        if self.table.prior is self.home_prior and moves:
            obs, masks, actions = zip(*moves)
            self.posterior.observe(np.stack(obs), np.stack(masks), np.array(actions))
            if self._planner is not None:  # the plan is the one thing that does not follow the evidence by itself
                self._player = self._new_player()


@dataclass(frozen=True)
class ConventionSource:
    """What every room's `ConventionAgent` shares, read-only: the training partners (the posterior's models), the trained ego's heads (`known`), the game's convention key and planner."""

    models: list[Partner]
    known: list[Partner]
    key: KeyFn | None
    planner: BestResponse | None = None

    def agent(self, table: AdaptiveAgent, home_prior: Prior, seed: int | list[int] | None = None) -> ConventionAgent:
        """A room's agent: `table` (the paper's agent for this person) inside a fresh posterior over this source's conventions."""
        return ConventionAgent(table, ConventionPosterior(self.models, self.key), self.known, home_prior, seed, self.planner)
