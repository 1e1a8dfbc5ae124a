"""The 2x2 collaborative block placing game (the paper's Section 6 and Appendix C.2).

A goal puts a red block and a blue block on two distinct cells of a 2x2 grid (12
goals, drawn at reset). P1 (`player_0`) owns the red block and sees the goal; P2
(`player_1`) owns the blue block and sees an all-hidden goal. Starting from an empty
working grid they alternate P1, P2, P1, P2, P1, P2. A move places the mover's block
on a cell (actions 0-3; the block leaves its old cell and evicts whatever was on the
new one), removes it (4) or passes (5). After the sixth move both players receive
+10 for each correctly placed block (max 20); no reward before that.

New task (`new_task=True`): the red block must end on a cell that is empty in the
goal; the blue target is unchanged, so P2's conventions still apply.

Cells are numbered row-major: 0 top-left, 1 top-right, 2 bottom-left, 3 bottom-right.
Observation (35 floats, one-hot): goal grid as the player sees it (4 cells x
{empty, red, blue, hidden}), working grid (4 cells x {empty, red, blue}), and the
move number 0..6 (6 once the game is over).
"""

from __future__ import annotations

from itertools import permutations
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv
from pettingzoo.utils import AgentSelector

from rllib_conv.envs.spaces import (
    MASK_KEY,
    OBS_KEY,
    check_choice,
    masked_observation_space,
    validate_action,
)

NUM_CELLS = 4
NUM_MOVES = 6
EMPTY, RED, BLUE, HIDDEN = 0, 1, 2, 3
REMOVE, PASS = 4, 5
NUM_ACTIONS = 6
CELL_REWARD = 10.0
# Every (red cell, blue cell) pair on distinct cells: the 12 goals.
GOALS: list[tuple[int, int]] = list(permutations(range(NUM_CELLS), 2))
OBS_DIM = NUM_CELLS * 4 + NUM_CELLS * 3 + NUM_MOVES + 1
ACTION_NAMES = ["place 0", "place 1", "place 2", "place 3", "remove", "pass"]


def encode_observation(goal: np.ndarray, grid: np.ndarray, move: int, sees_goal: bool) -> np.ndarray:
    """Return the 35-float one-hot observation of a player (see the module docstring)."""
    obs = np.zeros(OBS_DIM, dtype=np.float32)
    for cell in range(NUM_CELLS):
        obs[cell * 4 + (int(goal[cell]) if sees_goal else HIDDEN)] = 1.0
        obs[NUM_CELLS * 4 + cell * 3 + int(grid[cell])] = 1.0
    obs[NUM_CELLS * 7 + move] = 1.0
    return obs


def decode_observation(obs: np.ndarray) -> dict[str, Any]:
    """Invert `encode_observation`: return `goal` (4 codes, HIDDEN if unseen), `grid`, `move`."""
    seen = decode_observations(obs)
    seen["move"] = int(seen["move"])
    return seen


def decode_observations(obs: np.ndarray) -> dict[str, np.ndarray]:
    """`decode_observation` on rows [..., 35] at once: `goal` and `grid` [..., 4], `move` [...]."""
    obs = np.asarray(obs)
    lead = obs.shape[:-1]
    goal = obs[..., : NUM_CELLS * 4].reshape(*lead, NUM_CELLS, 4).argmax(axis=-1)
    grid = obs[..., NUM_CELLS * 4 : NUM_CELLS * 7].reshape(*lead, NUM_CELLS, 3).argmax(axis=-1)
    move = obs[..., NUM_CELLS * 7 :].argmax(axis=-1)
    return {"goal": goal, "grid": grid, "move": move}


def block_cell(grid: np.ndarray, colour: int) -> int | None:
    """Return the cell holding the block of `colour`, or None if it is off the grid."""
    cells = np.flatnonzero(np.asarray(grid) == colour)
    return int(cells[0]) if len(cells) else None


def apply_move(grid: np.ndarray, colour: int, action: int) -> np.ndarray:
    """Return the working grid after the owner of `colour` plays `action` (a new array).

    Placing moves the block (evicting whatever was on the new cell), REMOVE takes it off
    the grid, PASS changes nothing.
    """
    grid = np.array(grid, dtype=np.int64)
    if action < NUM_CELLS:
        grid[grid == colour] = EMPTY
        grid[action] = colour
    elif action == REMOVE:
        grid[grid == colour] = EMPTY
    return grid


def final_reward(goal: tuple[int, int], grid: np.ndarray, new_task: bool = False) -> float:
    """Return the shared end-of-game reward for a working `grid` and goal `(red, blue)`."""
    red_goal, blue_goal = goal
    red = block_cell(grid, RED)
    if new_task:
        red_ok = red is not None and red not in (red_goal, blue_goal)
    else:
        red_ok = red == red_goal
    return CELL_REWARD * (int(red_ok) + int(block_cell(grid, BLUE) == blue_goal))


class BlockPlacingEnv(AECEnv):
    """Two players rebuild a hidden 2x2 goal with one red and one blue block in 6 moves."""

    metadata = {"name": "blocks_v0", "render_modes": ["ansi"], "is_parallelizable": False}

    def __init__(self, new_task: bool = False, render_mode: str | None = None) -> None:
        super().__init__()
        if not isinstance(new_task, bool):
            raise ValueError(f"new_task must be a bool, got {new_task!r}")
        check_choice("render_mode", render_mode, [None, *self.metadata["render_modes"]])
        self.new_task = new_task
        self.render_mode = render_mode
        self.possible_agents = ["player_0", "player_1"]
        self.agents: list[str] = []
        self._colour = {"player_0": RED, "player_1": BLUE}
        self._obs_space = masked_observation_space(OBS_DIM, NUM_ACTIONS)
        self._act_space = spaces.Discrete(NUM_ACTIONS)
        self._mask = np.ones(NUM_ACTIONS, dtype=np.int8)
        self._rng = np.random.default_rng()
        self.goal: tuple[int, int] = GOALS[0]
        self.grid = np.zeros(NUM_CELLS, dtype=np.int64)
        self.move = 0
        self.history: list[tuple[str, int]] = []

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._act_space

    def goal_grid(self) -> np.ndarray:
        """Return the goal as 4 cell codes (EMPTY, RED, BLUE)."""
        goal = np.zeros(NUM_CELLS, dtype=np.int64)
        goal[self.goal[0]], goal[self.goal[1]] = RED, BLUE
        return goal

    def observe(self, agent: str) -> dict[str, np.ndarray]:
        obs = encode_observation(self.goal_grid(), self.grid, self.move, sees_goal=agent == "player_0")
        return {OBS_KEY: obs, MASK_KEY: self._mask.copy()}

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self.agents = list(self.possible_agents)
        self.goal = GOALS[int(self._rng.integers(len(GOALS)))]
        self.grid = np.zeros(NUM_CELLS, dtype=np.int64)
        self.move = 0
        self.history = []
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos = {a: {"goal": list(self.goal)} for a in self.agents}
        self._agent_selector = AgentSelector(self.agents)
        self.agent_selection = self._agent_selector.reset()

    def step(self, action: Any) -> None:
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        action = validate_action(action, self._mask, env="blocks", agent=agent)
        self.grid = apply_move(self.grid, self._colour[agent], action)
        self.history.append((agent, action))
        self.move += 1
        self._cumulative_rewards[agent] = 0.0
        self._clear_rewards()
        if self.move == NUM_MOVES:
            reward = final_reward(self.goal, self.grid, self.new_task)
            for a in self.agents:
                self.rewards[a] = reward
                self.terminations[a] = True
                self.infos[a]["score"] = reward
        self._accumulate_rewards()
        self.agent_selection = self._agent_selector.next()

    def render(self) -> str | None:
        if self.render_mode is None:
            return None
        sym = ".RB?"
        goal, grid = self.goal_grid(), self.grid
        lines = [f"move {self.move}/{NUM_MOVES}   goal    grid"]
        for row in range(2):
            g = "".join(sym[goal[row * 2 + i]] for i in range(2))
            w = "".join(sym[grid[row * 2 + i]] for i in range(2))
            lines.append(f"{'':14}{g}      {w}")
        return "\n".join(lines)

    def close(self) -> None:
        """Nothing to release; defined because PettingZoo requires close() beside render()."""
