"""Blocks partners: P2 reads where red lands on move 1 and answers with a fixed permutation.

A permutation partner with `perm` places blue on `perm[c]` if P1's first move put red
on cell `c`, and passes otherwise. The paper's 9 hand-designed partners are the 9
derangements of the 4 cells (no cell maps to itself), 3 for training and 6 for test.
`BlocksLeader` is the matching P1: it signals the blue goal through the permutation,
then moves red to its own goal; paired with its permutation partner it scores 20. The
built-in populations `blocks-perm[-newtask]` are declared here.
"""

from __future__ import annotations

from functools import partial
from itertools import permutations
from typing import Any

import numpy as np

from rllib_conv.envs.blocks import (
    BLUE,
    HIDDEN,
    NUM_CELLS,
    PASS,
    RED,
    block_cell,
    decode_observation,
    decode_observations,
)
from rllib_conv.partners.base import Partner, SampledPartner
from rllib_conv.partners.kinds import register_kind
from rllib_conv.partners.population import Population, from_partners, register_builtin, task_suffix

TRAIN_PERMUTATIONS: list[tuple[int, ...]] = [(1, 3, 0, 2), (2, 0, 3, 1), (3, 2, 1, 0)]


def derangements(n: int = NUM_CELLS) -> list[tuple[int, ...]]:
    """Return the permutations of range(n) with no fixed point, in lexicographic order."""
    return [p for p in permutations(range(n)) if all(p[i] != i for i in range(n))]


TEST_PERMUTATIONS: list[tuple[int, ...]] = [p for p in derangements() if p not in TRAIN_PERMUTATIONS]


def _check_permutation(perm: list[int]) -> tuple[int, ...]:
    perm = tuple(int(c) for c in perm)
    if sorted(perm) != list(range(NUM_CELLS)):
        raise ValueError(f"perm must be a permutation of 0..{NUM_CELLS - 1}, got {list(perm)}")
    return perm


@register_kind
class PermutationPartner(Partner):
    """P2 (blue): on its first move, places blue on `perm[red's cell]`; otherwise passes."""

    kind = "blocks_permutation"
    batchable = True  # a function of each observation (and its own RNG): it may choose for many games at once
    deterministic = True

    def __init__(self, name: str, perm: list[int]) -> None:
        super().__init__(name)
        self.perm = _check_permutation(perm)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return int(self.act_batch(np.asarray(observation)[None], np.asarray(action_mask)[None])[0])

    def act_batch(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        # Every row at once: this partner answers every training step of a blocks ego.
        seen = decode_observations(observations)
        red = seen["grid"] == RED
        actions = np.full(len(red), PASS, dtype=np.int64)
        follow = (seen["move"] == 1) & red.any(axis=-1)
        actions[follow] = np.asarray(self.perm, dtype=np.int64)[red.argmax(axis=-1)[follow]]
        return actions

    def params(self) -> dict[str, Any]:
        return {"perm": list(self.perm)}


@register_kind
class NoisyPermutationPartner(SampledPartner):
    """A `PermutationPartner` that slips: on its first move it places blue on a uniformly drawn cell with probability `noise`.

    It says what it draws from (`action_probs`), so blocks' exact return and P1's
    best-response bound score it without sampling; the bound is below 20 once `noise > 0`.
    """

    kind = "blocks_noisy_permutation"

    def __init__(self, name: str, perm: list[int], noise: float) -> None:
        super().__init__(name)
        self.perm = _check_permutation(perm)
        if not 0.0 <= float(noise) <= 1.0:
            raise ValueError(f"noise must be a probability from 0 to 1, got {noise!r}")
        self.noise = float(noise)
        self._exact = PermutationPartner(name, list(self.perm))

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        exact = self._exact.action_probs(observations, action_masks)
        seen = decode_observations(observations)
        slips = (seen["move"] == 1) & (seen["grid"] == RED).any(axis=-1)  # where it places blue at all
        exact[slips] *= 1.0 - self.noise
        exact[slips, :NUM_CELLS] += self.noise / NUM_CELLS
        return exact

    def params(self) -> dict[str, Any]:
        return {"perm": list(self.perm), "noise": self.noise}


@register_kind
class BlocksLeader(Partner):
    """P1 (red) that knows the partner's `perm`: the best response to `PermutationPartner(perm)`.

    Move 0: put red on the cell the partner reads as the blue goal; move 2: put red on
    its goal (on the new task, the first goal-empty cell); move 4: pass.
    """

    kind = "blocks_leader"
    batchable = True  # a function of each observation (and its own RNG): it may choose for many games at once
    deterministic = True

    def __init__(self, name: str, perm: list[int], new_task: bool = False) -> None:
        super().__init__(name)
        self.perm = _check_permutation(perm)
        self.new_task = bool(new_task)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        obs = decode_observation(observation)
        goal = obs["goal"]
        if HIDDEN in goal:
            raise ValueError("BlocksLeader plays P1 and needs to see the goal")
        blue_goal, red_goal = block_cell(goal, BLUE), block_cell(goal, RED)
        if obs["move"] == 0:
            return self.perm.index(blue_goal)
        if obs["move"] == 2:
            if self.new_task:
                return next(c for c in range(NUM_CELLS) if c not in (red_goal, blue_goal))
            return red_goal
        return PASS

    def params(self) -> dict[str, Any]:
        return {"perm": list(self.perm), "new_task": self.new_task}


def blocks_permutations(new_task: bool) -> Population:
    """The 9 derangement partners (P2): 3 train, 6 test, as in the paper."""
    return from_partners(
        f"blocks-perm{task_suffix(new_task)}",
        "blocks",
        {"new_task": new_task},
        [PermutationPartner(f"perm-{''.join(map(str, p))}", list(p)) for p in TRAIN_PERMUTATIONS],
        [PermutationPartner(f"perm-{''.join(map(str, p))}", list(p)) for p in TEST_PERMUTATIONS],
        description="P2 places blue at perm[red's cell after move 1], then passes",
    )


for _new in (False, True):
    register_builtin(f"blocks-perm{task_suffix(_new)}", partial(blocks_permutations, _new))
