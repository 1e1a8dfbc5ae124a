"""A game that lives in the tests only: a 2-player PettingZoo env, its record and a scripted partner kind.

Named by import path (`GAME`), so Ray workers import it on first use, like a user's own game:
one step, two contexts seen by both players, three actions; both score 1 when they choose the
same good action. Context 0 has two good actions (a convention to settle), context 1 one (a rule).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from rllib_conv.envs.defaults import AdaptDefaults, TrainingDefaults
from rllib_conv.envs.game import GameRecord, OracleFn
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY, masked_observation_space, validate_action
from rllib_conv.partners.base import Partner
from rllib_conv.partners.population import Population, from_partners

GAME = "tests.games.tiny:TINY"  # how configs, populations and the CLI name it
GOOD = np.array([[1, 1, 0], [0, 0, 1]], dtype=np.float32)  # [context, action]: 1 where the action is good
CONTEXTS, ACTIONS = GOOD.shape


class TinyEnv(ParallelEnv):
    """Two players, one step: 1 each if both choose the same good action of the context."""

    metadata = {"name": "tiny_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self) -> None:
        self.possible_agents = ["player_0", "player_1"]
        self.agents: list[str] = []
        self._space = masked_observation_space(CONTEXTS, ACTIONS)
        self._rng = np.random.default_rng()
        self.context = 0

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._space

    def action_space(self, agent: str) -> spaces.Discrete:
        return spaces.Discrete(ACTIONS)

    def _observe(self) -> dict[str, np.ndarray]:
        return {OBS_KEY: np.eye(CONTEXTS, dtype=np.float32)[self.context], MASK_KEY: np.ones(ACTIONS, dtype=np.int8)}

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self.context = int(self._rng.integers(CONTEXTS))
        return {a: self._observe() for a in self.agents}, {a: {} for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        chosen = [validate_action(actions[a], np.ones(ACTIONS, dtype=np.int8), env="tiny", agent=a) for a in self.possible_agents]
        reward = float(GOOD[self.context, chosen[0]]) if chosen[0] == chosen[1] else 0.0
        obs = {a: self._observe() for a in self.agents}
        done = {a: True for a in self.agents}
        result = obs, {a: reward for a in self.agents}, done, {a: False for a in self.agents}, {a: {} for a in self.agents}
        self.agents = []
        return result

    def close(self) -> None:
        """Nothing to release."""


def tiny_oracle() -> OracleFn:
    """The good actions of the observed context."""
    return lambda obs: np.asarray(obs, dtype=np.float32) @ GOOD


class TinyConvention(Partner):
    """Chooses `arm` in context 0 and the only good action in context 1."""

    kind = GAME.replace("TINY", "TinyConvention")  # found by import path in every process
    deterministic = True

    def __init__(self, name: str, arm: int) -> None:
        super().__init__(name)
        self.arm = int(arm)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return self.arm if int(np.argmax(observation)) == 0 else ACTIONS - 1

    def params(self) -> dict[str, Any]:
        return {"arm": self.arm}


def population(name: str = "tiny-pop") -> Population:
    """Two training partners (one per convention of context 0) and two test partners."""
    return from_partners(
        name,
        GAME,
        {},
        [TinyConvention("left", 0), TinyConvention("right", 1)],
        [TinyConvention("left-test", 0), TinyConvention("right-test", 1)],
    )


TINY = GameRecord(
    name="tiny",
    env=TinyEnv,
    title="Tiny test game",
    training=TrainingDefaults(hidden=8, rollout_per_partner=32, minibatch_size=16, num_epochs=2, timesteps=256),
    adaptation=AdaptDefaults(every=16, steps=48),
    oracle=tiny_oracle,
    convention_key=lambda observation: int(np.argmax(observation)),
    max_score=1.0,
)
