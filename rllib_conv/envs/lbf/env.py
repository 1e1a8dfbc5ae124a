"""Level-Based Foraging (Albrecht & Ramamoorthy 2013; `lbforaging`, Christianos et al.) as a PettingZoo ParallelEnv.

`players` (2-4) foragers with levels 1..`max_player_level` and `food` items on a `size` x
`size` field. Each step every player moves (north, south, west, east), waits, or loads an
adjacent food; a food is collected when the players loading it together have levels summing to
at least its level (`coop=True`: every food needs all the players' levels). The episode
terminates when every food is collected and is truncated after `horizon` steps.

The dynamics and observations are `lbforaging==2.0.0`'s `ForagingEnv`, with one change: its
step resolves loads in the iteration order of a set of player objects, which CPython orders
by memory address, so two envs under one seed could split a contested food differently.
Here every player hashes to its seat index, so loads resolve in seat order, the same in
every process.

Rewards: the package gives each loader `level * food_level`, normalised so that collecting
every food sums to 1 over the team. The players are one team here (the library's games are
fully cooperative): with `shared_reward=True` (the default) every player gets the team's sum
each step, so an episode scores the fraction of food (by level) collected, at most 1.
`infos[agent]["own_reward"]` keeps the package's own share.

Observations: `{"observation": lbforaging's flat vector (see `observation.py`), "action_mask":
the package's valid actions}`; a move into food or off the field, or a load with no food
adjacent, is masked, and a masked action raises (the package would quietly turn it into none).
"""

from __future__ import annotations

import importlib
from functools import cache
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from rllib_conv.envs.lbf.observation import NUM_ACTIONS
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY, validate_action

MIN_PLAYERS, MAX_PLAYERS = 2, 4
MIN_SIZE = 5  # the smallest field lbforaging registers: food keeps a cell from the edge and from other food
MAX_FOOD = 9
HORIZON = 50  # lbforaging's registered episode length


@cache
def _package() -> tuple[type, type]:
    """lbforaging's `ForagingEnv`, and its `Player` hashing to its seat index (sets of players iterate in seat order).

    Imported on the first env built, not with this module: importing `lbforaging` registers its
    1,920 gymnasium ids (0.6-1.2 s), and every command imports the game registry.
    """
    environment = importlib.import_module("lbforaging.foraging.environment")

    class SeatPlayer(environment.Player):
        def __init__(self, index: int) -> None:
            super().__init__()
            self.index = index

        def __hash__(self) -> int:
            return self.index

    return environment.ForagingEnv, SeatPlayer


def _positive_int(name: str, value: Any, low: int = 1, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low or (high is not None and value > high):
        span = f"an integer in [{low}, {high}]" if high is not None else f"an integer >= {low}"
        raise ValueError(f"lbf: {name} must be {span}, got {value!r}")
    return int(value)


def _flag(name: str, value: Any) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"lbf: {name} must be true or false, got {value!r}")
    return value


class LBFEnv(ParallelEnv):
    """Level-Based Foraging for 2-4 players acting at once (see the module docstring)."""

    metadata = {"name": "lbf_v0", "render_modes": ["ansi"], "is_parallelizable": True}

    def __init__(
        self,
        players: int = 3,
        size: int = 8,
        food: int = 3,
        sight: int | None = None,
        horizon: int = HORIZON,
        max_player_level: int = 2,
        coop: bool = False,
        shared_reward: bool = True,
        render_mode: str | None = None,
    ) -> None:
        self.num_players = _positive_int("players", players, MIN_PLAYERS, MAX_PLAYERS)
        self.size = _positive_int("size", size, MIN_SIZE)
        # At most `food` items: the package places fewer where the field has no room (food keeps off the edge and apart).
        self.food = _positive_int("food", food, 1, MAX_FOOD)
        self.sight = self.size if sight is None else _positive_int("sight", sight, 1, self.size)
        self.horizon = _positive_int("horizon", horizon)
        self.max_player_level = _positive_int("max_player_level", max_player_level)
        self.coop = _flag("coop", coop)
        self.shared_reward = _flag("shared_reward", shared_reward)
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"lbf: render_mode must be one of {[None, *self.metadata['render_modes']]}, got {render_mode!r}")
        self.render_mode = render_mode
        foraging_env, seat_player = _package()
        self._env = foraging_env(
            players=self.num_players,
            min_player_level=1,
            max_player_level=self.max_player_level,
            min_food_level=1,
            max_food_level=None,  # the package's default: up to the sum of the three lowest player levels
            field_size=(self.size, self.size),
            max_num_food=self.food,
            sight=self.sight,
            max_episode_steps=self.horizon,
            force_coop=self.coop,
            normalize_reward=True,
            grid_observation=False,
            observe_agent_levels=True,
        )
        self._env.players = [seat_player(i) for i in range(self.num_players)]
        self.possible_agents = [f"player_{i}" for i in range(self.num_players)]
        self.agents: list[str] = []
        inner = self._env.observation_space[0]
        self._obs_space = spaces.Dict(
            {
                OBS_KEY: spaces.Box(inner.low, inner.high, dtype=np.float32),
                MASK_KEY: spaces.Box(0, 1, shape=(NUM_ACTIONS,), dtype=np.int8),
            }
        )
        self._act_space = spaces.Discrete(NUM_ACTIONS)
        self._masks: list[np.ndarray] = []

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._act_space

    @property
    def forage(self) -> Any:
        """The package's `ForagingEnv` underneath (its `field` and `players` are the state)."""
        return self._env

    def masks(self) -> list[np.ndarray]:
        """Each seat's int8 mask of valid actions now."""
        out = []
        for player in self._env.players:
            mask = np.zeros(NUM_ACTIONS, dtype=np.int8)
            mask[[a.value for a in self._env._valid_actions[player]]] = 1
            out.append(mask)
        return out

    def observe(self) -> dict[str, dict[str, np.ndarray]]:
        """Every seat's observation of the current state, recomputed (a test that edits `forage`'s state calls it)."""
        self._env._gen_valid_moves()
        return self._pack(self._env._make_gym_obs())

    def _pack(self, vectors: tuple[np.ndarray, ...]) -> dict[str, dict[str, np.ndarray]]:
        self._masks = self.masks()  # the next step checks its actions against these
        return {
            agent: {OBS_KEY: np.asarray(vec, dtype=np.float32), MASK_KEY: mask.copy()}
            for agent, vec, mask in zip(self.possible_agents, vectors, self._masks)
        }

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """Spawn players and food anew (from `seed` when given, else the env's generator going on)."""
        vectors, _ = self._env.reset(seed=seed)
        self.agents = list(self.possible_agents)
        return self._pack(vectors), {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise ValueError("lbf: step() after the episode ended; call reset() first")
        missing = [agent for agent in self.possible_agents if agent not in actions]
        if missing:
            raise ValueError(f"lbf: no action for {', '.join(missing)}; step needs one for each of {self.possible_agents}")
        joint = [
            validate_action(actions[agent], mask, env="lbf", agent=agent)
            for agent, mask in zip(self.possible_agents, self._masks)
        ]
        vectors, own, _, _, _ = self._env.step(joint)
        team = float(sum(own))
        rewards = {agent: team if self.shared_reward else float(r) for agent, r in zip(self.possible_agents, own)}
        infos = {agent: {"own_reward": float(r)} for agent, r in zip(self.possible_agents, own)}
        terminated = bool(self._env.field.sum() == 0)
        truncated = not terminated and self._env.current_step >= self.horizon
        observations = self._pack(vectors)
        terminations = {agent: terminated for agent in self.possible_agents}
        truncations = {agent: truncated for agent in self.possible_agents}
        if terminated or truncated:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def render(self) -> str | None:
        """The field as text: food by its level, players by letter (A is player_0), '.' empty."""
        if self.render_mode is None:
            return None
        grid = [["." if v == 0 else str(v) for v in row] for row in self._env.field]
        for i, player in enumerate(self._env.players):
            row, col = player.position
            grid[row][col] = chr(ord("A") + i)
        return "\n".join("".join(row) for row in grid)

    def close(self) -> None:
        """Nothing to release (no window is opened); defined because PettingZoo requires close() beside render()."""
