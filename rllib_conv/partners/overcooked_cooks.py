"""Scripted Overcooked cooks with conventions: who fetches onions, who plates, which pot, which onion pile.

A `ConventionCook` plays from its observation alone (the lossless grid of
`envs.overcooked.encoding`, read back here), like any other `Partner`. Its convention is
three choices a human pair settles without saying so (Carroll et al. 2019, Sec. 5):
- `role`: `"onions"` only fills pots, `"dishes"` only plates and serves, `"both"` does
  whatever the kitchen needs next (fill a pot that is not full, else plate a soup);
- `pot`: which pot it fills and plates from (0, 1, ... in reading order), or -1 for the nearest;
- `onions`: which onion pile it fetches from (reading order), or -1 for the nearest.
The rules of the kitchen (an onion goes into a pot that is not cooking, a soup is plated
with a dish, a plated soup goes to the serving spot) are the same for every cook: these
partners differ in conventions only, which is what the modular ego's task module and
partner modules are meant to separate.

It moves along a shortest path on the floor (breadth-first, around its partner), turns to
face what it wants and interacts; with nothing to do it stays, out of its partner's way. Where
its partner stands in every way, or near it while it has nothing to do, it takes a random step (uniform over the four moves and stay, from its own seeded
generator), as Carroll et al.'s scripted agents do to get unstuck; everywhere else its
move is a function of the observation. `action_probs` says which.

Built-in populations `overcooked-<layout>-cooks` (`COOK_LAYOUTS`: the classic layouts but
forced_coordination): every distinct convention of the layout; every third is held out for
testing. Conventions matter: two onion cooks, or cooks faithful to different pots, score 0
together, while a matching pair delivers (tests/partners/test_overcooked_cooks.py).
"""

from __future__ import annotations

from collections import deque
from functools import partial
from typing import Any

import numpy as np

from rllib_conv.envs.overcooked.encoding import CHANNELS, GridEncoder
from rllib_conv.envs.overcooked.env import CLASSIC_LAYOUTS, EAST, INTERACT, NORTH, SOUTH, STAY, WEST, build_mdp
from rllib_conv.envs.spaces import check_choice
from rllib_conv.partners.base import Partner
from rllib_conv.partners.kinds import register_kind
from rllib_conv.partners.population import Population, from_partners, register_builtin

ROLES = ("onions", "dishes", "both")
_C = {name: i for i, name in enumerate(CHANNELS)}
_TERRAIN = [_C[c] for c in ("pot", "counter", "onion_dispenser", "tomato_dispenser", "dish_dispenser", "serving")]
# (dx, dy) of each move action; a move into a wall only turns the cook to face it.
_MOVES = {NORTH: (0, -1), SOUTH: (0, 1), EAST: (1, 0), WEST: (-1, 0)}
_FACING = ("ego_facing_north", "ego_facing_south", "ego_facing_east", "ego_facing_west")
_BLOCKED = -1  # the partner stands in every way to the target: a random step (Carroll et al.'s agents "unstick" so too)


def _cells(plane: np.ndarray) -> list[tuple[int, int]]:
    """The (x, y) cells where `plane[y, x]` is set, in reading order (row by row)."""
    return [(int(x), int(y)) for y, x in np.argwhere(plane > 0)]


@register_kind
class ConventionCook(Partner):
    """A scripted cook with a convention (`role`, `pot`, `onions`); see the module docstring."""

    kind = "overcooked_cook"
    batchable = True  # a function of each observation (and its own RNG): it may choose for many games at once

    def __init__(
        self, name: str, layout: str = "cramped_room", role: str = "both", pot: int = -1, onions: int = -1, seed: int = 0
    ) -> None:
        super().__init__(name)
        self._seed = int(seed)
        self._rng = np.random.default_rng(self._seed)
        check_choice("role", role, ROLES)
        mdp = build_mdp(layout)
        self.layout, self.role, self.pot, self.onions = layout, role, int(pot), int(onions)
        self.shape = GridEncoder(mdp, 1).shape
        terrain = np.zeros(self.shape[1:], dtype=bool)
        grid = np.array(mdp.terrain_mtx)
        terrain[:] = grid != " "
        self.floor = ~terrain
        self.pots = sorted(mdp.get_pot_locations(), key=lambda p: (p[1], p[0]))
        self.onion_piles = sorted(mdp.get_onion_dispenser_locations(), key=lambda p: (p[1], p[0]))
        self.dish_piles = list(mdp.get_dish_dispenser_locations())
        self.serving = list(mdp.get_serving_locations())
        for what, index, known in (("pot", self.pot, self.pots), ("onions", self.onions, self.onion_piles)):
            if not -1 <= index < len(known):
                raise ValueError(f"{what} must be -1 (nearest) or 0..{len(known) - 1} on layout {layout!r}, got {index}")

    def params(self) -> dict[str, Any]:
        return {"layout": self.layout, "role": self.role, "pot": self.pot, "onions": self.onions, "seed": self._seed}

    def seed(self, seed: int | None) -> None:
        self._rng = np.random.default_rng(self._seed if seed is None else seed)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        p = self.action_probs(np.asarray(observation)[None], np.asarray(action_mask)[None])[0]
        return int(np.argmax(p)) if p.max() == 1.0 else int(self._rng.choice(len(p), p=p))

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """One-hot of the scripted move, or uniform over the moves and stay where the partner blocks every way."""
        out = np.zeros(np.shape(action_masks), dtype=np.float64)
        for row, observation in enumerate(observations):
            choice = self._choose(np.asarray(observation, dtype=np.float32).reshape(self.shape))
            if choice == _BLOCKED:
                out[row, [NORTH, SOUTH, EAST, WEST, STAY]] = 0.2
            else:
                out[row, choice] = 1.0
        return out

    def _choose(self, grid: np.ndarray) -> int:
        me = _cells(grid[_C["ego_position"]])[0]
        partner = _cells(grid[_C["partner_position"]])[0]
        facing = next(_MOVES[a] for a, ch in zip((NORTH, SOUTH, EAST, WEST), _FACING) if grid[_C[ch]][me[1], me[0]] > 0)
        targets = self._targets(grid, me)
        if targets:
            return self._go(me, facing, partner, targets)
        # Nothing to do: keep still, unless the partner is near (then this cook is likely in its way).
        return _BLOCKED if abs(me[0] - partner[0]) + abs(me[1] - partner[1]) <= 2 else STAY

    def _targets(self, grid: np.ndarray, me: tuple[int, int]) -> list[tuple[int, int]]:
        """The cells this cook wants to interact with next, by its convention (empty: nothing to do)."""
        x, y = me
        holds = {what: grid[_C[what]][y, x] > 0 for what in ("onions", "dishes", "soup_done")}
        holds["soup"] = holds["soup_done"] or grid[_C["onions_in_soup"]][y, x] > 0
        fillable = [
            p for p in self.pots if grid[_C["onions_in_pot"]][p[1], p[0]] < 1 and grid[_C["onions_in_soup"]][p[1], p[0]] == 0
        ]
        cooking = [p for p in self.pots if grid[_C["onions_in_soup"]][p[1], p[0]] > 0]
        mine = (lambda cells: cells) if self.pot < 0 else (lambda cells: [c for c in cells if c == self.pots[self.pot]])
        if holds["soup"]:
            return self.serving
        if holds["dishes"]:
            done = [p for p in mine(cooking) if grid[_C["soup_done"]][p[1], p[0]] > 0]
            return done or mine(cooking)  # wait beside a cooking soup
        if holds["onions"]:
            return mine(fillable)
        fetch_onions = self.role != "dishes" and bool(mine(fillable))
        if fetch_onions:
            return self.onion_piles if self.onions < 0 else [self.onion_piles[self.onions]]
        if self.role != "onions" and mine(cooking):
            return self.dish_piles
        return []

    def _go(self, me: tuple[int, int], facing: tuple[int, int], partner: tuple[int, int], targets: list[tuple[int, int]]) -> int:
        """Interact when facing a target from beside it, else the first move of a shortest path to a cell beside one."""
        for t in targets:
            if (t[0] - me[0], t[1] - me[1]) == facing:
                return INTERACT
        for t in targets:  # beside a target but facing elsewhere: turn (a move into a non-floor cell only turns)
            for action, (dx, dy) in _MOVES.items():
                if (me[0] + dx, me[1] + dy) == t:
                    return action
        goals = {(t[0] + dx, t[1] + dy) for t in targets for dx, dy in _MOVES.values() if self._free(t[0] + dx, t[1] + dy)}
        step = self._first_step(me, goals - {partner}, blocked={partner})
        if step is None:  # the partner is in the way: head its way (it may move), or step aside at random beside it
            step = self._first_step(me, goals, blocked=set())
            if step is None or (me[0] + _MOVES[step][0], me[1] + _MOVES[step][1]) == partner:
                return _BLOCKED
        return step

    def _free(self, x: int, y: int) -> bool:
        return 0 <= y < self.floor.shape[0] and 0 <= x < self.floor.shape[1] and bool(self.floor[y, x])

    def _first_step(self, start: tuple[int, int], goals: set[tuple[int, int]], blocked: set[tuple[int, int]]) -> int | None:
        """The first move of a shortest floor path from `start` to any of `goals` (ties: north, south, east, west)."""
        first: dict[tuple[int, int], int | None] = {start: None}
        queue = deque([start])
        while queue:
            cell = queue.popleft()
            if cell in goals:
                return first[cell]
            for action, (dx, dy) in _MOVES.items():
                nxt = (cell[0] + dx, cell[1] + dy)
                if nxt not in first and self._free(*nxt) and nxt not in blocked:
                    first[nxt] = action if first[cell] is None else first[cell]
                    queue.append(nxt)
        return None


def conventions(layout: str) -> list[dict[str, Any]]:
    """Every distinct convention on `layout`: role x pot x onion pile (a choice the role never uses left at -1)."""
    mdp = build_mdp(layout)
    pots = range(len(mdp.get_pot_locations())) if len(mdp.get_pot_locations()) > 1 else [-1]
    piles = range(len(mdp.get_onion_dispenser_locations())) if len(mdp.get_onion_dispenser_locations()) > 1 else [-1]
    out = []
    for role in ROLES:
        for pot in pots:
            for onions in piles if role != "dishes" else [-1]:
                out.append({"role": role, "pot": pot, "onions": onions})
    return out


def _name(convention: dict[str, Any]) -> str:
    """`onions-pot1-pile0`; a choice left to the nearest reads `any`."""
    pot, pile = (("any" if convention[k] < 0 else str(convention[k])) for k in ("pot", "onions"))
    return f"{convention['role']}-pot{pot}-pile{pile}"


def overcooked_cooks(layout: str) -> Population:
    """The population of `layout`'s convention cooks; every third convention is held out for testing."""
    cooks = [ConventionCook(_name(c), layout, **c) for c in conventions(layout)]
    test = cooks[2::3]
    train = [c for c in cooks if c not in test]
    return from_partners(
        f"overcooked-{layout}-cooks",
        "overcooked",
        {"layout": layout},
        train,
        test,
        description=f"scripted Overcooked cooks on {layout}: role x pot x onion pile conventions; every third held out",
    )


# forced_coordination is left out: its cooks stand on two sides of a wall and must hand
# ingredients over a counter, which these cooks never do (every pair scores 0 there).
COOK_LAYOUTS = tuple(layout for layout in CLASSIC_LAYOUTS if layout != "forced_coordination")
for _layout in COOK_LAYOUTS:
    register_builtin(f"overcooked-{_layout}-cooks", partial(overcooked_cooks, _layout))
