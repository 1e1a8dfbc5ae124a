"""Level-Based Foraging's heuristic partners H1-H4 (Albrecht & Ramamoorthy 2013), as `lbforaging` defines them.

`lbforaging==2.0.0` ships them (`lbforaging/agents/heuristic_agent.py`) but they do not import
(`from foraging.environment import Action`), and they read the package's `Observation` object,
not the vector a policy sees. They are written again here from that file, on the vector
(`envs.lbf.observation`); `tests/partners/test_lbf_heuristics.py` checks every move against the
package's own code on played states. Each type picks a target food from what it sees:

- H1: the food nearest to itself;
- H2: the food nearest to the centre of the visible players (itself included);
- H3: the food nearest to itself among those of a level it can load alone (<= its level);
- H4: the food nearest to the centre of the visible players among those they can load
  together (<= the sum of their levels).

"Nearest" is by squared Euclidean distance, the first in reading order on a tie; the centre
is the players' mean position rounded half to even (`np.rint`). Next to its target (one step
away, not diagonally) it loads; otherwise it steps toward it, trying north, south, east, west
in that order (a row first, then a column), each only if that move is legal. With no target
food in sight, or no legal step toward it, it takes a legal action uniformly at random, from
its own seeded generator: `action_probs` says which.

Built-in population `lbf-heuristics`: the default 3-player game, the partners in `player_1`
and `player_2`; H1 and H2 train (every episode seats one of them in each partner seat), H3
and H4, their level-aware variants, are held out. `lbf-heldout-types` trains with H3 and H4:
an ego trained with them is the trained best response that bounds the held-out evaluation set.
"""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np

from rllib_conv.envs.lbf.env import LBFEnv
from rllib_conv.envs.lbf.observation import EAST, LOAD, NORTH, SOUTH, WEST, SeenState, read_observation
from rllib_conv.envs.spaces import check_choice
from rllib_conv.partners.base import SampledPartner
from rllib_conv.partners.kinds import register_kind
from rllib_conv.partners.population import Population, from_partners, register_builtin

RULES = ("H1", "H2", "H3", "H4")
# The env's defaults, which a partner built without `food` and `players` reads observations of.
_ENV_DEFAULTS = {name: p.default for name, p in inspect.signature(LBFEnv).parameters.items()}


def heuristic_target(seen: SeenState, rule: str) -> tuple[int, int] | None:
    """The (row, col) of the food `rule` goes for in `seen`, or None when none qualifies (see the module docstring)."""
    check_choice("rule", rule, list(RULES))
    me, players, food = seen.me, seen.players, seen.food
    start = np.rint(players[:, :2].mean(axis=0)) if rule in ("H2", "H4") else me[:2]
    limit = {"H3": me[2], "H4": players[:, 2].sum()}.get(rule)
    if limit is not None:
        food = food[food[:, 2] <= limit]
    if not len(food):
        return None
    nearest = int(np.argmin(((food[:, :2] - start) ** 2).sum(axis=1)))
    return int(food[nearest, 0]), int(food[nearest, 1])


def heuristic_probs(seen: SeenState, rule: str, action_mask: np.ndarray) -> np.ndarray:
    """[6]: the probability of each action of a `rule` player that sees `seen` with legal actions `action_mask`."""
    mask = np.asarray(action_mask, dtype=np.float64)
    target = heuristic_target(seen, rule)
    if target is not None:
        (r, c), (y, x) = target, seen.me[:2]
        if abs(r - y) + abs(c - x) == 1:
            return np.eye(len(mask))[LOAD]
        for wanted, move in ((r < y, NORTH), (r > y, SOUTH), (c > x, EAST), (c < x, WEST)):
            if wanted and mask[move]:
                return np.eye(len(mask))[move]
    return mask / mask.sum()


@register_kind
class LBFHeuristic(SampledPartner):
    """A heuristic forager of type `rule` (H1-H4); see the module docstring.

    `food` and `players` are the env's (its defaults by default): they say how to read its observation vector.
    """

    kind = "lbf_heuristic"

    def __init__(
        self, name: str, rule: str = "H1", food: int = _ENV_DEFAULTS["food"], players: int = _ENV_DEFAULTS["players"]
    ) -> None:
        super().__init__(name)
        check_choice("rule", rule, list(RULES))
        for what, value in (("food", food), ("players", players)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{what} must be the env's {what} (an integer >= 1), got {value!r}")
        self.rule, self.food, self.players = rule, food, players

    def params(self) -> dict[str, Any]:
        return {"rule": self.rule, "food": self.food, "players": self.players}

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        p = self.action_probs(np.asarray(observation)[None], np.asarray(action_mask)[None])[0]
        # A scripted move draws nothing, so the generator's draws are the random moves alone.
        return int(np.argmax(p)) if p.max() == 1.0 else int(self._rng.choice(len(p), p=p))

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        return np.stack(
            [
                heuristic_probs(read_observation(o, self.food, self.players), self.rule, m)
                for o, m in zip(observations, action_masks)
            ]
        )


def _three_players(name: str, train: tuple[str, ...], test: tuple[str, ...], description: str) -> Population:
    """A 3-player population of heuristic types (`train`, `test`: rules), the partners in `player_1` and `player_2`."""
    return from_partners(
        name,
        "lbf",
        {"players": 3},
        [LBFHeuristic(rule, rule=rule) for rule in train],
        [LBFHeuristic(rule, rule=rule) for rule in test],
        description=description,
        partner_agent=["player_1", "player_2"],
    )


def lbf_heuristics() -> Population:
    """The 3-player population of heuristic foragers: H1 and H2 to train with, H3 and H4 held out."""
    return _three_players(
        "lbf-heuristics",
        ("H1", "H2"),
        ("H3", "H4"),
        "Level-Based Foraging's heuristic types, 3 players: H1, H2 train; H3, H4 (level-aware) held out",
    )


def lbf_heldout_types() -> Population:
    """H3 and H4 as training partners (no test split): trains the best responses that bound the held-out LBF set."""
    return _three_players(
        "lbf-heldout-types",
        ("H3", "H4"),
        (),
        "Level-Based Foraging's held-out types H3, H4 to train with: an ego trained with them is a best response to them "
        "(the bounds of tune_configs/eval_sets/lbf_heldout.yaml)",
    )


register_builtin("lbf-heuristics", lbf_heuristics)
register_builtin("lbf-heldout-types", lbf_heldout_types)
