"""The collaborative contextual bandit (the paper's Section 3 and Appendix C.1).

Each episode is one step: a context is drawn, both players see it and pull an arm,
and both receive `prizes[context, arm]` if they pulled the same arm, else 0.

Built-in tasks (arms and contexts are 0-based here; the paper counts from 1):
- `task="paper"`: 4 contexts x 8 arms. Contexts `c < symmetric` have two good arms
  `{c, c + 4}` (conventions); the other contexts have one good arm `{c}` (rules).
  `new_task=True` moves the rule contexts' good arm to `c + 4` and leaves the
  symmetric contexts unchanged (the paper's "tweaked task").
- `task="user_study"`: the 3 x 4 user-study task: Train, or Test with `new_task=True`.
- `prizes=[[...], ...]`: any contexts x arms prize matrix (overrides `task`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from rllib_conv.common.user_study_table import USER_STUDY_ARMS, USER_STUDY_GOOD_ARMS
from rllib_conv.envs.spaces import (
    MASK_KEY,
    OBS_KEY,
    check_choice,
    masked_observation_space,
    validate_action,
)

PAPER_CONTEXTS = 4
PAPER_ARMS = 8

TASKS = ["paper", "user_study"]


def paper_prizes(symmetric: int, new_task: bool = False) -> np.ndarray:
    """Return the paper's 4 x 8 prize matrix with `symmetric` contexts of two good arms."""
    check_choice("symmetric", symmetric, range(PAPER_CONTEXTS + 1))
    prizes = np.zeros((PAPER_CONTEXTS, PAPER_ARMS), dtype=np.float32)
    for c in range(PAPER_CONTEXTS):
        if c < symmetric:
            prizes[c, [c, c + PAPER_CONTEXTS]] = 1.0
        else:
            prizes[c, c + PAPER_CONTEXTS if new_task else c] = 1.0
    return prizes


def user_study_prizes(new_task: bool = False) -> np.ndarray:
    """Return the user study's 3 x 4 prize matrix: Train, or Test if `new_task`."""
    good = USER_STUDY_GOOD_ARMS["test" if new_task else "train"]
    prizes = np.zeros((len(good), USER_STUDY_ARMS), dtype=np.float32)
    for c, arms in enumerate(good):
        prizes[c, list(arms)] = 1.0
    return prizes


def good_arms(prizes: np.ndarray) -> list[tuple[int, ...]]:
    """Return, per context, the arms with the highest prize (the optimal joint actions)."""
    return [tuple(np.flatnonzero(row == row.max()).tolist()) for row in prizes]


def oracle_marginals(prizes: np.ndarray) -> np.ndarray:
    """Return the true marginal best response: uniform over each context's good arms."""
    optimal = (prizes == prizes.max(axis=1, keepdims=True)).astype(np.float64)
    return optimal / optimal.sum(axis=1, keepdims=True)


class CollaborativeBanditEnv(ParallelEnv):
    """Two players, one step: prize `prizes[context, arm]` if both pull the same arm."""

    metadata = {"name": "bandit_v0", "render_modes": ["ansi"], "is_parallelizable": True}

    def __init__(
        self,
        task: str = "paper",
        symmetric: int = 2,
        new_task: bool = False,
        prizes: list[list[float]] | np.ndarray | None = None,
        render_mode: str | None = None,
    ) -> None:
        check_choice("render_mode", render_mode, [None, *self.metadata["render_modes"]])
        if not isinstance(new_task, bool):
            raise ValueError(f"new_task must be a bool, got {new_task!r}")
        if prizes is not None:
            prizes = np.asarray(prizes, dtype=np.float32)
            if prizes.ndim != 2 or prizes.shape[0] < 1 or prizes.shape[1] < 2:
                raise ValueError(
                    f"prizes must be a contexts x arms matrix with >= 1 context and >= 2 arms, got shape {prizes.shape}"
                )
            if not np.isfinite(prizes).all() or (prizes < 0).any():
                raise ValueError("prizes must be finite and non-negative")
        else:
            check_choice("task", task, TASKS)
            prizes = paper_prizes(symmetric, new_task) if task == "paper" else user_study_prizes(new_task)
        self.prizes = prizes
        self.num_contexts, self.num_arms = prizes.shape
        self.render_mode = render_mode
        self.possible_agents = ["player_0", "player_1"]
        self.agents: list[str] = []
        self._obs_space = masked_observation_space(self.num_contexts, self.num_arms)
        self._act_space = spaces.Discrete(self.num_arms)
        self._mask = np.ones(self.num_arms, dtype=np.int8)
        self._rng = np.random.default_rng()
        self.context = 0
        self.last_actions: dict[str, int] = {}

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._act_space

    def _observe(self) -> dict[str, np.ndarray]:
        obs = np.zeros(self.num_contexts, dtype=np.float32)
        obs[self.context] = 1.0
        return {OBS_KEY: obs, MASK_KEY: self._mask.copy()}

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self.context = int(self._rng.integers(self.num_contexts))
        self.last_actions = {}
        info = {"context": self.context}
        return {a: self._observe() for a in self.agents}, {a: dict(info) for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("bandit: step() called on a finished episode; call reset() first")
        missing = set(self.agents) - set(actions)
        if missing:
            raise ValueError(f"bandit: step() needs an action for every agent; missing {sorted(missing)}")
        arms = {a: validate_action(actions[a], self._mask, env="bandit", agent=a) for a in self.agents}
        a0, a1 = (arms[a] for a in self.possible_agents)
        reward = float(self.prizes[self.context, a0]) if a0 == a1 else 0.0
        self.last_actions = arms
        obs = {a: self._observe() for a in self.agents}
        info = {"context": self.context, "actions": [a0, a1]}
        result = (
            obs,
            {a: reward for a in self.agents},
            {a: True for a in self.agents},
            {a: False for a in self.agents},
            {a: dict(info) for a in self.agents},
        )
        self.agents = []
        return result

    def render(self) -> str | None:
        if self.render_mode is None:
            return None
        rows = []
        for c, row in enumerate(self.prizes):
            cells = " ".join("#" if p > 0 else "." for p in row)
            mark = " <- " + str(self.last_actions) if c == self.context else ""
            rows.append(f"context {c}: {cells}{mark}")
        return "\n".join(rows)

    def close(self) -> None:
        """Nothing to release; defined because PettingZoo requires close() beside render()."""
