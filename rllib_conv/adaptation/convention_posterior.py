"""The convention posterior (not in the paper): which known convention is a new partner following?

A trained modular ego holds one head per training partner: its best response to that
partner's conventions. A new partner is judged from its own moves against models of the
training partners (the partners themselves: what the ego played with for all of training),
under two kinds of hypothesis:

- **whole convention k**: the new partner plays as training partner k does, in every
  situation; the ego answers with head k;
- **recombination**: in each situation (a game's convention key, `envs.convention_keys`;
  every move its own situation where a game has none) the partner follows one of the
  known conventions or a novel one, chosen afresh per situation. Where the situation has
  been seen, the ego answers with the heads of the conventions it may be following there;
  where it has not, or the convention is novel, with its adapting head (the task module
  plus a fresh head that PPO fine-tunes: the paper's adapter, whose start is the task
  module's estimate of the population's marginal).

Each move's likelihood under known convention k is the training partner's probability of
it, smoothed with `epsilon` of the uniform distribution over legal moves (a model is never
certain); a novel convention is uniform. Priors: `recombined` on recombination, the rest
split evenly over the whole conventions; within a situation `novel` on a novel convention.

On the bandit a recombination-posterior of known conventions is what the adapter that is
Bayes-optimal under a uniform prior over conventions does (a seen context's arm is known,
an unseen one is the marginal). Where a game
can plan against a partner model (`envs.best_response`; blocks, with the ego as P1), the
ego plays the best response to the posterior's prediction of the partner's moves
(`ConventionPosterior.predictive`) instead of choosing among heads: a partner that mixes
known conventions observation by observation, or follows a new one, is answered as well
as the evidence allows. On Hanabi (no key, no planner) a partner who follows a training
partner's convention is identified within a few moves, and one who follows none falls to
the adapting head, i.e. to the paper's method.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from rllib_conv.common.seeds import member_seed
from rllib_conv.envs.best_response import BestResponse
from rllib_conv.envs.convention_keys import KeyFn
from rllib_conv.modules import ego_id
from rllib_conv.partners.base import Partner
from rllib_conv.partners.kinds import gives_action_probs
from rllib_conv.partners.population import Population
from rllib_conv.training.evaluate import ego_head_partner

MAX_REMEMBERED = 100_000  # model probabilities kept per posterior (and its copies) before starting afresh


def logsumexp(x: np.ndarray, axis: int = -1) -> np.ndarray:
    """log(sum(exp(x))) along `axis`, stably; SciPy's costs 0.2 ms a call, which is most of playing one bandit episode."""
    top = np.max(x, axis=axis, keepdims=True)
    return np.squeeze(top, axis=axis) + np.log(np.sum(np.exp(x - top), axis=axis))


@dataclass(frozen=True)
class KnownConventions:
    """What a trained modular ego knows of its training partners: the partners (the posterior's models) and its head for each (module IDs, and as players)."""

    models: list[Partner]
    head_ids: list[str]
    heads: list[Partner]


def require_action_probs(population: Population, what: str) -> None:
    """ValueError naming `what` unless every training partner of `population` gives its action probabilities (the posterior models them)."""
    opaque = [e.name for e in population.entries("train") if not gives_action_probs(e.kind)]
    if opaque:
        raise ValueError(f"{what} models the training partners, but {opaque} do not give their action probabilities")


def known_conventions(population: Population, module: Any, what: str) -> KnownConventions:
    """The training partners of `population` and the trained ego `module`'s head for each (`require_action_probs` first)."""
    require_action_probs(population, what)
    train = population.entries("train")
    head_ids = [ego_id(e.name) for e in train]
    return KnownConventions([e.build() for e in train], head_ids, [ego_head_partner(module, mid) for mid in head_ids])


class ConventionPosterior:
    """Posterior over K whole known conventions and recombination, from a new partner's observed moves (see the module docstring).

    `models` are the K training partners (their `action_probs`), `key` the game's
    convention key (None: every move its own situation).
    """

    def __init__(
        self, models: Sequence[Partner], key: KeyFn | None, recombined: float = 0.5, novel: float = 0.1, epsilon: float = 0.05
    ) -> None:
        if not models:
            raise ValueError("the convention posterior needs at least one known partner model")
        for name, value in (("recombined", recombined), ("novel", novel), ("epsilon", epsilon)):
            if not 0.0 < value < 1.0:
                raise ValueError(f"{name} must be in (0, 1), got {value}")
        k = len(models)
        self.models, self.key, self.epsilon = list(models), key, epsilon
        self._log_prior = np.log(np.array([(1.0 - recombined) / k] * k + [recombined]))
        self._log_part_prior = np.log(np.array([(1.0 - novel) / k] * k + [novel]))
        self._whole = np.zeros(k)  # log-likelihood of every move under whole convention k
        self._unkeyed = 0.0  # log-likelihood under recombination of the moves without a situation key
        self._parts: dict[int, np.ndarray] = {}  # situation key -> log-likelihood of its moves per (known k..., novel)
        self._counts: dict[int, np.ndarray] = {}  # situation key -> how often the partner played each action there
        self._hypotheses: np.ndarray | None = None  # `hypotheses()` until the next `observe`
        # (observation, mask) bytes -> the models' action probabilities [K, A]; the models never change, so copies share it.
        self._model_probs: dict[tuple[bytes, bytes], np.ndarray] = {}

    @property
    def num_known(self) -> int:
        """K, the number of known conventions."""
        return len(self.models)

    def model_probs(self, observations: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """[N, K, A]: every model's action probabilities per row, each distinct row computed once."""
        observations, masks = np.asarray(observations), np.asarray(masks)
        keys = [(o.tobytes(), m.tobytes()) for o, m in zip(observations, masks)]
        todo = list({key: i for i, key in enumerate(keys) if key not in self._model_probs}.values())  # one row per new key
        if todo:
            if len(self._model_probs) > MAX_REMEMBERED:
                self._model_probs.clear()
            probs = np.stack([m.action_probs(observations[todo], masks[todo]) for m in self.models], axis=1)
            self._model_probs.update(zip((keys[i] for i in todo), probs))
        return np.stack([self._model_probs[key] for key in keys])

    def smoothed_probs(self, observations: np.ndarray, masks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """([N, K, A], [N, A]): every known convention's move probabilities with `epsilon` of uniform legal play mixed in, and that uniform play."""
        legal = np.asarray(masks, dtype=np.float64)
        uniform = legal / legal.sum(axis=1, keepdims=True)
        return (1.0 - self.epsilon) * self.model_probs(observations, masks) + self.epsilon * uniform[:, None, :], uniform

    def move_likelihoods(self, observations: np.ndarray, masks: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """[N, K + 1]: each move's probability under known convention k (smoothed) and under a novel one (uniform)."""
        known, uniform = self.smoothed_probs(observations, masks)
        rows, actions = np.arange(len(uniform)), np.asarray(actions, dtype=np.int64)
        return np.concatenate([known[rows, :, actions], uniform[rows, actions][:, None]], axis=1)

    def observe(self, observations: np.ndarray, masks: np.ndarray, actions: np.ndarray) -> None:
        """Add the partner's moves (observations [N, d], masks [N, A], actions [N]) to the evidence."""
        if len(actions) == 0:
            return
        self._hypotheses = None
        log_lik = np.log(self.move_likelihoods(observations, masks, actions))
        self._whole += log_lik[:, : self.num_known].sum(axis=0)
        if self.key is None:
            self._unkeyed += float(logsumexp(self._log_part_prior + log_lik, axis=1).sum())
            return
        played = np.eye(np.shape(masks)[1])[np.asarray(actions, dtype=np.int64)]
        for obs, row, one_hot in zip(observations, log_lik, played):
            key = self.key(obs)
            self._parts[key] = self._parts.get(key, 0.0) + row  # new arrays: copies keep theirs
            self._counts[key] = self._counts.get(key, 0.0) + one_hot

    def hypotheses(self) -> np.ndarray:
        """[K + 1]: the posterior of whole convention k, and last of recombination."""
        if self._hypotheses is None:
            self._hypotheses = self._posterior()
        return self._hypotheses

    def whole(self) -> np.ndarray:
        """[K]: the posterior of whole convention k given that the partner follows one whole (their prior is even).

        Computed from the whole conventions' own likelihoods, so it stays defined however strongly the evidence favours
        recombination (`hypotheses()[:-1]` may then underflow to zero): PLASTIC's belief over known types
        (`adaptation.plastic`).
        """
        return np.exp(self._whole - logsumexp(self._whole))

    def _posterior(self) -> np.ndarray:
        recombined = self._unkeyed + sum(float(logsumexp(self._log_part_prior + part)) for part in self._parts.values())
        log_post = self._log_prior + np.append(self._whole, recombined)
        return np.exp(log_post - logsumexp(log_post))

    def situation(self, key: int | None) -> np.ndarray | None:
        """[K + 1]: under recombination, the posterior of known convention k and last of a novel one in situation `key`; None if unseen."""
        part = self._parts.get(key) if key is not None else None
        if part is None:
            return None
        log_post = self._log_part_prior + part
        return np.exp(log_post - logsumexp(log_post))

    def predictive(self, observations: np.ndarray, masks: np.ndarray) -> np.ndarray:
        """[N, A]: the probability of each partner move in each observation, given the evidence.

        Whole convention k by its posterior predicts its (smoothed) model; recombination
        predicts by the situation's posterior (its prior where unseen), a novel convention
        there by the moves seen in it (counts plus one half; uniform where unseen).
        """
        known, uniform = self.smoothed_probs(observations, masks)
        legal = np.asarray(masks, dtype=np.float64)
        post = self.hypotheses()
        out = np.einsum("k,nka->na", post[:-1], known)
        part_prior = np.exp(self._log_part_prior)
        for n, obs in enumerate(np.asarray(observations)):
            key = self.key(obs) if self.key else None
            part, counts = self.situation(key), self._counts.get(key)
            part = part_prior if part is None else part
            novel = uniform[n] if counts is None else (counts + 0.5) * legal[n] / ((counts + 0.5) * legal[n]).sum()
            out[n] += post[-1] * (part[:-1] @ known[n] + part[-1] * novel)
        return out

    def copy(self) -> "ConventionPosterior":
        """An independent copy of the evidence (the models are shared)."""
        other = object.__new__(ConventionPosterior)
        other.__dict__.update(self.__dict__)
        # `observe` replaces a situation's arrays, never changes them.
        other._whole, other._parts, other._counts = self._whole.copy(), dict(self._parts), dict(self._counts)
        return other


class PosteriorPlayer(Partner):
    """The ego playing by a `ConventionPosterior`: as a `Partner`, for `play_episodes` (evaluation, the web app's agent).

    `known[k]` answers whole convention k (the trained ego with head k); `adapting` is the
    adapting head (task module + the new head). `handed`: the known convention whose head
    the adapting head was started from (it then answers that convention too). Each episode
    starts from `posterior` (the evidence of the env steps played so far) and updates a
    copy with the partner's moves in the episode. The player samples a hypothesis per
    episode and keeps it while its posterior stays above `switch` times the best one's;
    under recombination it samples, at each move, a convention from that situation's
    posterior. `action_probs` is the mixture this draws from before any move of the
    episode (exact on one-step games).

    With a `planner` (a game's `envs.best_response`), the player instead plays the best
    response to `posterior`'s prediction of the partner's moves (planned once, from the
    evidence before the episode). A plan has a legal move at every move of its seat (the
    `Plan` contract), so nothing the player sees within an episode changes its play: it is
    then a fixed policy, scored by a game's exact return and played many games at once.
    """

    kind = "convention_posterior"

    def __init__(
        self,
        name: str,
        posterior: ConventionPosterior,
        known: Sequence[Partner],
        adapting: Partner,
        handed: int | None = None,
        seed: int = 0,
        switch: float = 0.5,
        planner: BestResponse | None = None,
    ) -> None:
        super().__init__(name)
        if len(known) != posterior.num_known:
            raise ValueError(f"{len(known)} known heads for a posterior over {posterior.num_known} conventions")
        self.posterior, self.adapting, self.handed, self.switch = posterior, adapting, handed, switch
        self.plan = planner.plan(posterior.predictive(*planner.situations())) if planner else None
        self.known = [adapting if k == handed else head for k, head in enumerate(known)]
        self._seed = seed
        self._rng = np.random.default_rng(seed)
        self.start_episode()

    @property
    def learns_in_play(self) -> bool:  # type: ignore[override]
        """Without a plan the partner's moves in an episode steer its hypotheses; with one they change no move."""
        return self.plan is None

    @property
    def batchable(self) -> bool:  # type: ignore[override]
        """A planned player's move is a function of its observation alone."""
        return self.plan is not None

    def seed(self, seed: int | None) -> None:
        self._rng = np.random.default_rng(self._seed if seed is None else seed)
        for i, player in enumerate([*self.known, self.adapting]):
            player.seed(None if seed is None else member_seed(seed, i))

    def params(self) -> dict:
        return {"handed": self.handed, "seed": self._seed}

    def start_episode(self) -> None:
        self._live = self.posterior.copy()
        self._hypothesis = self._draw(self._live.hypotheses())

    def observe_other(self, observation: np.ndarray, action_mask: np.ndarray, action: int, agent: str | None = None) -> None:
        self._live.observe(np.asarray(observation)[None], np.asarray(action_mask)[None], np.array([action]))
        post = self._live.hypotheses()
        if post[self._hypothesis] < self.switch * post.max():
            self._hypothesis = self._draw(post)

    def _draw(self, p: np.ndarray) -> int:
        return int(min(np.searchsorted(np.cumsum(p), self._rng.random() * p.sum(), side="right"), len(p) - 1))

    def _planned(self, observation: np.ndarray, action_mask: np.ndarray) -> int | None:
        action = self.plan.act(observation) if self.plan else None
        return action if action is not None and action_mask[action] else None

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        planned = self._planned(observation, action_mask)
        if planned is not None:
            return planned
        if self._hypothesis < len(self.known):
            return self.known[self._hypothesis].act(observation, action_mask)
        key = self._live.key(np.asarray(observation)) if self._live.key else None
        part = self._live.situation(key)
        if part is None:
            return self.adapting.act(observation, action_mask)
        z = self._draw(part)
        return (self.known[z] if z < len(self.known) else self.adapting).act(observation, action_mask)

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        observations, action_masks = np.asarray(observations), np.asarray(action_masks)
        planned = [self._planned(obs, mask) for obs, mask in zip(observations, action_masks)]
        if self.plan is not None and None not in planned:  # the plan's moves alone: no head needs to run
            return np.eye(action_masks.shape[1])[planned]
        post = self.posterior.hypotheses()
        answers = np.stack([p.action_probs(observations, action_masks) for p in [*self.known, self.adapting]])  # [K + 1, B, A]
        out = np.tensordot(post[:-1], answers[:-1], axes=1)
        key = self.posterior.key
        for b, obs in enumerate(observations):
            part = self.posterior.situation(key(obs) if key else None)
            out[b] += post[-1] * (answers[-1, b] if part is None else np.tensordot(part, answers[:, b], axes=1))
            if planned[b] is not None:
                out[b] = np.eye(out.shape[1])[planned[b]]
        return out
