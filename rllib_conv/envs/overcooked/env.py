"""Overcooked-AI (Carroll et al., NeurIPS 2019) as a PettingZoo ParallelEnv over the maintained MDP.

Two cooks (`player_0`, `player_1`) share a kitchen: they fetch onions, fill a pot with
three, wait for the soup to cook (20 ticks), plate it with a dish and deliver it to the
serving spot. The dynamics are `overcooked==0.2.1`'s `OvercookedGridworld` with
`old_dynamics=True` (a full pot starts cooking on its own, as in the 2019 human data), and
its `get_state_transition`; the package's `Overcooked` gym wrapper and `featurize_state`
are not used (the first crashes when no pot is empty, the second does not run).

Actions are indices into `ACTIONS` (the package's `Action.ALL_ACTIONS`): 0 north (up),
1 south, 2 east, 3 west, 4 stay, 5 interact; every action is always legal. Rewards: the
sparse reward (20 per soup delivered, to both players) plus `shaping` times the MDP's
shaped reward (3 per ingredient potted, 3 per useful dish pickup, 5 per soup picked up),
by default the team's total (as Carroll et al.'s 2019 code), or each player's own with
`shared_shaping=False`. With `hidden_utility` ({seat: {event: weight}}) a seat is rewarded by the
weighted count of its own kitchen events instead (HSP's biased partners, `hidden_utility.py`).
`infos[agent]` carries `sparse_reward` and `shaped_reward` apart, so
evaluation can report the sparse score alone, and `events`, the kitchen events that seat caused; the shaping schedule is in `shaping.py`.
An episode is truncated when the state's timestep reaches `horizon` (400 in the paper).

Replays: `reset(options={"state": OvercookedState})` starts from that state (its timestep
counts towards the horizon) and `env.state` is the current `OvercookedState`.
Observations: `encoding.GridEncoder`, each seat seeing itself first.

`Recipe` is configured globally by the package each time an MDP is built; the env puts its
layout's recipe configuration back before it steps, so envs of layouts with different
recipes can share a process.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from gymnasium import spaces
from overcooked.mdp.actions import Action
from overcooked.mdp.overcooked_mdp import OvercookedGridworld, OvercookedState, Recipe
from overcooked.static import LAYOUTS_DIR
from pettingzoo import ParallelEnv

from rllib_conv.envs.overcooked.encoding import GridEncoder
from rllib_conv.envs.overcooked.hidden_utility import HiddenUtility, check_hidden_utility, event_reward, events_of
from rllib_conv.envs.overcooked.shaping import shaping_factor
from rllib_conv.envs.spaces import MASK_KEY, OBS_KEY, check_choice, masked_observation_space, validate_action

# The package's actions in index order: the policy's action i is ACTIONS[i].
ACTIONS: tuple = tuple(Action.ALL_ACTIONS)
ACTION_NAMES: tuple[str, ...] = ("north", "south", "east", "west", "stay", "interact")
NORTH, SOUTH, EAST, WEST, STAY, INTERACT = range(len(ACTIONS))
NUM_ACTIONS = len(ACTIONS)
_ACTION_INDEX = {action: i for i, action in enumerate(ACTIONS)}

# Carroll et al.'s five layouts (the 2019 human data's random0 and random3 are the 3rd and 5th's old names).
CLASSIC_LAYOUTS: tuple[str, ...] = (
    "cramped_room",
    "asymmetric_advantages",
    "coordination_ring",
    "forced_coordination",
    "counter_circuit_o_1order",
)
AGENTS = ("player_0", "player_1")
HORIZON = 400  # Carroll et al.'s episode length


def action_index(action: Any) -> int:
    """The index in `ACTIONS` of one of the package's `Action` values (a direction tuple, `(0, 0)` or "interact")."""
    key = tuple(action) if isinstance(action, list) else action
    try:
        return _ACTION_INDEX[key]
    except (KeyError, TypeError):
        raise ValueError(f"not an Overcooked action: {action!r}; actions: {list(ACTIONS)}") from None


def layouts() -> tuple[str, ...]:
    """Every layout the package ships, Carroll et al.'s five first (some are not 2-player 3-onion kitchens: see `build_mdp`)."""
    shipped = sorted(name[: -len(".layout")] for name in os.listdir(LAYOUTS_DIR) if name.endswith(".layout"))
    return CLASSIC_LAYOUTS + tuple(name for name in shipped if name not in CLASSIC_LAYOUTS)


def build_mdp(layout: str) -> OvercookedGridworld:
    """The 2019-dynamics MDP of `layout`; ValueError naming the known layouts, or why this one cannot be played."""
    known = layouts()
    if layout not in known:
        raise ValueError(f"unknown Overcooked layout {layout!r}; known layouts: {', '.join(known)}")
    try:
        mdp = OvercookedGridworld.from_layout_name(layout, old_dynamics=True)
    except AssertionError as exc:
        # The 2019 dynamics cook any full pot on its own, so the package allows only 3-ingredient orders with them.
        raise ValueError(f"Overcooked layout {layout!r} cannot run with the 2019 dynamics: {exc}") from None
    if mdp.num_players != len(AGENTS):
        raise ValueError(f"Overcooked layout {layout!r} has {mdp.num_players} players; this env plays 2")
    return mdp


class OvercookedEnv(ParallelEnv):
    """Overcooked-AI, two players acting at once (see the module docstring)."""

    metadata = {"name": "overcooked_v0", "render_modes": ["ansi"], "is_parallelizable": True}

    def __init__(
        self,
        layout: str = "cramped_room",
        horizon: int = HORIZON,
        shaping: float = 1.0,
        shaping_horizon: int | None = None,
        shared_shaping: bool = True,
        hidden_utility: HiddenUtility | None = None,
        render_mode: str | None = None,
    ) -> None:
        if not isinstance(horizon, int) or isinstance(horizon, bool) or horizon <= 0:
            raise ValueError(f"horizon must be a positive integer (steps per episode), got {horizon!r}")
        if shaping_horizon is not None:
            shaping_factor(0, shaping_horizon)  # raises on a bad horizon
        if not isinstance(shared_shaping, bool):
            raise ValueError(f"shared_shaping must be a bool, got {shared_shaping!r}")
        check_choice("render_mode", render_mode, [None, *self.metadata["render_modes"]])
        self.mdp = build_mdp(layout)
        self.layout = layout
        self.horizon = horizon
        self.set_shaping(shaping)
        self.shaping_horizon = shaping_horizon
        self.shared_shaping = shared_shaping
        self.hidden_utility = None if hidden_utility is None else check_hidden_utility(hidden_utility, AGENTS)
        self.render_mode = render_mode
        self.steps_taken = 0  # env steps since construction: the clock of `shaping_horizon`
        self.possible_agents = list(AGENTS)
        self.agents: list[str] = []
        self._recipes = self.mdp.recipe_config
        self.encoder = GridEncoder(self.mdp, horizon)
        self._obs_space = masked_observation_space(self.encoder.size, NUM_ACTIONS)
        self._act_space = spaces.Discrete(NUM_ACTIONS)
        self._mask = np.ones(NUM_ACTIONS, dtype=np.int8)
        self._state: OvercookedState = self.mdp.get_standard_start_state()

    def observation_space(self, agent: str) -> spaces.Dict:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Discrete:
        return self._act_space

    def set_shaping(self, shaping: float) -> None:
        """Set the factor on the shaped reward (the start of the schedule when `shaping_horizon` is set)."""
        if isinstance(shaping, bool) or not isinstance(shaping, int | float) or not np.isfinite(shaping) or shaping < 0:
            raise ValueError(f"shaping must be a finite number >= 0, got {shaping!r}")
        self.shaping = float(shaping)

    def shaping_now(self) -> float:
        """The factor the next step's shaped reward is multiplied by."""
        if self.shaping_horizon is None:
            return self.shaping
        return shaping_factor(self.steps_taken, self.shaping_horizon, start=self.shaping)

    @property
    def state(self) -> OvercookedState:
        """A copy of the current `OvercookedState` (a replay compares it with the logged one)."""
        return self._state.deepcopy()

    def _observe(self) -> dict[str, dict[str, np.ndarray]]:
        seats = self.encoder.encode(self._state)
        return {agent: {OBS_KEY: obs, MASK_KEY: self._mask.copy()} for agent, obs in zip(AGENTS, seats)}

    def _use_recipes(self) -> None:
        # The package keeps one recipe configuration for the whole process; another layout's MDP may have replaced ours.
        if Recipe._conf is not self._recipes:
            Recipe.configure(self._recipes)

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        """Start an episode from the layout's start state, or from `options["state"]` (an `OvercookedState`)."""
        # Other option keys are ignored, as PettingZoo's API test expects of every env.
        self._use_recipes()
        state = (options or {}).get("state")
        if state is None:
            state = self.mdp.get_standard_start_state()
        else:
            self._check_start(state)
        # Our copy: the caller's state object stays theirs.
        self._state = state.deepcopy()
        self.agents = list(self.possible_agents)
        return self._observe(), {agent: {} for agent in self.agents}

    def _check_start(self, state: Any) -> None:
        if not isinstance(state, OvercookedState):
            raise ValueError(f"overcooked: options['state'] must be an OvercookedState, got {type(state).__name__}")
        if not 0 <= state.timestep < self.horizon:
            raise ValueError(
                f"overcooked: options['state'] has timestep {state.timestep}; it must be in [0, horizon={self.horizon})"
            )
        if len(state.players) != len(AGENTS):
            raise ValueError(f"overcooked: options['state'] has {len(state.players)} players; this env plays 2")
        try:
            self.mdp.get_actions(state)  # the package's state check (players on floor, objects on terrain, ...)
        except AssertionError:
            raise ValueError(f"overcooked: options['state'] is not a valid state of layout {self.layout!r}: {state}") from None

    def step(self, actions: dict[str, Any]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise ValueError("overcooked: step() after the episode ended; call reset() first")
        missing = [agent for agent in AGENTS if agent not in actions]
        if missing:
            raise ValueError(f"overcooked: no action for {', '.join(missing)}; step needs one for each of {list(AGENTS)}")
        joint = tuple(ACTIONS[validate_action(actions[agent], self._mask, env="overcooked", agent=agent)] for agent in AGENTS)
        self._use_recipes()
        factor = self.shaping_now()
        self._state, info = self.mdp.get_state_transition(self._state, joint)
        self.steps_taken += 1
        sparse = float(sum(info["sparse_reward_by_agent"]))
        own = info["shaped_reward_by_agent"]
        shaped = [float(sum(own))] * len(AGENTS) if self.shared_shaping else [float(r) for r in own]
        rewards = {agent: sparse + factor * shaped[i] for i, agent in enumerate(AGENTS)}
        for seat, weights in (self.hidden_utility or {}).items():
            rewards[seat] = event_reward(info["event_infos"], weights, AGENTS.index(seat))
        infos = {
            agent: {
                "sparse_reward": sparse,
                "shaped_reward": shaped[i],
                "shaping": factor,
                "events": events_of(info["event_infos"], i),
            }
            for i, agent in enumerate(AGENTS)
        }
        done = self._state.timestep >= self.horizon
        observations = self._observe()
        terminations = {agent: False for agent in AGENTS}
        truncations = {agent: done for agent in AGENTS}
        if done:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def render(self) -> str | None:
        if self.render_mode is None:
            return None
        return self.mdp.state_string(self._state)

    def close(self) -> None:
        """Nothing to release; defined because PettingZoo requires close() beside render()."""
