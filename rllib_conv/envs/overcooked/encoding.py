"""Our lossless grid encoding of an Overcooked state, seen from one seat (ego channels first).

The package's own `lossless_state_encoding` rebuilds every layer in Python each step and its
`featurize_state` is broken in `overcooked==0.2.1`; this one keeps the same 26 channels (so
a reader of Carroll et al.'s code recognises them) but builds them with flat numpy writes:
the terrain channels are laid down once per layout, the objects once per state, and each
seat only adds the two players. One policy can play either seat, because channel 0 is
always "me" and channel 1 "my partner".

A player's observation is `grid.reshape(-1)` of a float32 array `grid[channel, y, x]`
(`GridEncoder.shape` is `(NUM_CHANNELS, height, width)`; `y` is the row, 0 at the top, as
in the layout files). Counts are scaled into [0, 1] so every value fits one Box:

| channels | meaning (value at the cell) |
|---|---|
| 0, 1 | ego's / partner's position (1) |
| 2-5, 6-9 | ego's / partner's facing north, south, east, west (1 at its cell) |
| 10-15 | terrain: pot, counter, onion dispenser, tomato dispenser, dish dispenser, serving spot |
| 16, 17 | onions / tomatoes in a pot that has not started cooking (count / 3) |
| 18, 19 | onions / tomatoes in a cooking or cooked soup, in a pot or held (count / 3) |
| 20 | a pot's soup: cook time remaining (ticks / the layout's longest recipe time) |
| 21 | a soup that is done (in a pot, held, or on a counter) |
| 22, 23, 24 | a dish / an onion / a tomato, loose on a counter or held (1) |
| 25 | urgency: 1 on every cell when fewer than 40 steps are left in the episode |

A held object sits on its holder's cell, so "ego holds an onion" is channel 23 at the cell
of channel 0.
"""

from __future__ import annotations

import numpy as np
from overcooked.mdp.actions import Direction
from overcooked.mdp.overcooked_mdp import OvercookedGridworld, OvercookedState, Recipe

CHANNELS: tuple[str, ...] = (
    "ego_position",
    "partner_position",
    "ego_facing_north",
    "ego_facing_south",
    "ego_facing_east",
    "ego_facing_west",
    "partner_facing_north",
    "partner_facing_south",
    "partner_facing_east",
    "partner_facing_west",
    "pot",
    "counter",
    "onion_dispenser",
    "tomato_dispenser",
    "dish_dispenser",
    "serving",
    "onions_in_pot",
    "tomatoes_in_pot",
    "onions_in_soup",
    "tomatoes_in_soup",
    "soup_cook_time_remaining",
    "soup_done",
    "dishes",
    "onions",
    "tomatoes",
    "urgency",
)
NUM_CHANNELS = len(CHANNELS)
CHANNEL = {name: i for i, name in enumerate(CHANNELS)}
# Terrain letters of the layout files, in the order of channels 10-15.
TERRAIN_LETTERS = ("P", "X", "O", "T", "D", "S")
URGENCY_STEPS = 40  # Carroll et al.'s encoding flags the last 40 steps of an episode
# Direction.ALL_DIRECTIONS is (north, south, east, west): the order of channels 2-5 and 6-9.
FACING = {direction: i for i, direction in enumerate(Direction.ALL_DIRECTIONS)}

_EGO, _PARTNER = CHANNEL["ego_position"], CHANNEL["partner_position"]
_EGO_FACING, _PARTNER_FACING = CHANNEL["ego_facing_north"], CHANNEL["partner_facing_north"]
_ONIONS_IN_POT, _TOMATOES_IN_POT = CHANNEL["onions_in_pot"], CHANNEL["tomatoes_in_pot"]
_ONIONS_IN_SOUP, _TOMATOES_IN_SOUP = CHANNEL["onions_in_soup"], CHANNEL["tomatoes_in_soup"]
_COOK_LEFT, _DONE = CHANNEL["soup_cook_time_remaining"], CHANNEL["soup_done"]
_LOOSE = {"dish": CHANNEL["dishes"], "onion": CHANNEL["onions"], "tomato": CHANNEL["tomatoes"]}
_URGENCY = CHANNEL["urgency"]


class GridEncoder:
    """Encode states of one layout as the two players' flat float32 observations (see the module docstring)."""

    def __init__(self, mdp: OvercookedGridworld, horizon: int) -> None:
        self.width, self.height = mdp.width, mdp.height
        self.shape = (NUM_CHANNELS, self.height, self.width)
        self.size = NUM_CHANNELS * self.height * self.width
        self.horizon = int(horizon)
        self._cells = self.height * self.width
        self._pots = frozenset(mdp.get_pot_locations())
        self._max_ingredients = float(Recipe.MAX_NUM_INGREDIENTS)
        # The layout's recipes fix how long a soup can cook: the scale that keeps channel 20 in [0, 1].
        self._cook_scale = float(max(recipe.time for recipe in Recipe.ALL_RECIPES()))
        terrain = np.zeros(self.shape, dtype=np.float32)
        for offset, letter in enumerate(TERRAIN_LETTERS):
            for x, y in mdp.terrain_pos_dict.get(letter, []):
                terrain[CHANNEL["pot"] + offset, y, x] = 1.0
        self._terrain = terrain.reshape(-1)
        self._urgency = slice(_URGENCY * self._cells, (_URGENCY + 1) * self._cells)

    def _at(self, channel: int, position: tuple[int, int]) -> int:
        """The flat index of `channel` at cell `(x, y)`."""
        x, y = position
        return channel * self._cells + y * self.width + x

    def _put_object(self, grid: np.ndarray, obj) -> None:
        position = obj.position
        if obj.name != "soup":
            grid[self._at(_LOOSE[obj.name], position)] = 1.0
            return
        ingredients = obj.ingredients
        onions = ingredients.count("onion") / self._max_ingredients
        tomatoes = ingredients.count("tomato") / self._max_ingredients
        if position in self._pots and obj.is_idle:
            grid[self._at(_ONIONS_IN_POT, position)] = onions
            grid[self._at(_TOMATOES_IN_POT, position)] = tomatoes
            return
        grid[self._at(_ONIONS_IN_SOUP, position)] = onions
        grid[self._at(_TOMATOES_IN_SOUP, position)] = tomatoes
        if position in self._pots:
            # A soup in a pot has started cooking (idle ones returned above): how long it has left.
            left = max(obj.cook_time - obj._cooking_tick, 0) / self._cook_scale
            grid[self._at(_COOK_LEFT, position)] = min(left, 1.0)
            if obj.is_ready:
                grid[self._at(_DONE, position)] = 1.0
        else:
            # Out of a pot a soup can only have been picked up cooked (as Carroll et al. encode it).
            grid[self._at(_DONE, position)] = 1.0

    def shared(self, state: OvercookedState) -> np.ndarray:
        """The channels both seats see alike (terrain, objects, urgency), flat."""
        grid = self._terrain.copy()
        for obj in state.objects.values():
            self._put_object(grid, obj)
        for player in state.players:
            if player.held_object is not None:
                self._put_object(grid, player.held_object)
        if self.horizon - state.timestep < URGENCY_STEPS:
            grid[self._urgency] = 1.0
        return grid

    def encode(self, state: OvercookedState) -> tuple[np.ndarray, np.ndarray]:
        """Both players' observations, each from its own seat: `(player_0's, player_1's)`."""
        shared = self.shared(state)
        first, second = state.players
        return self._seat(shared, first, second), self._seat(shared, second, first)

    def _seat(self, shared: np.ndarray, ego, partner) -> np.ndarray:
        grid = shared.copy()
        grid[self._at(_EGO, ego.position)] = 1.0
        grid[self._at(_EGO_FACING + FACING[ego.orientation], ego.position)] = 1.0
        grid[self._at(_PARTNER, partner.position)] = 1.0
        grid[self._at(_PARTNER_FACING + FACING[partner.orientation], partner.position)] = 1.0
        return grid

    def unflatten(self, observation: np.ndarray) -> np.ndarray:
        """An observation (or rows of them) back as `[..., channel, y, x]`."""
        observation = np.asarray(observation)
        return observation.reshape(*observation.shape[:-1], *self.shape)
