"""Bandit partners: a fixed arm per context (a convention), hand-designed or drawn at random, or drawn from given arm probabilities; their built-in populations."""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np

from rllib_conv.envs.bandit import PAPER_ARMS, PAPER_CONTEXTS, good_arms, paper_prizes
from rllib_conv.envs.spaces import check_choice
from rllib_conv.partners.base import Partner, SampledPartner
from rllib_conv.partners.kinds import register_kind
from rllib_conv.partners.population import Population, from_partners, register_builtin, task_suffix

HAND_DESIGNED_PER_SPLIT = 4
RANDOM_PER_SPLIT = 10


@register_kind
class BanditConventionPartner(Partner):
    """Pulls `arms[context]` in every context (the context is the one-hot observation)."""

    kind = "bandit_convention"
    batchable = True  # a function of each observation (and its own RNG): it may choose for many games at once
    deterministic = True

    def __init__(self, name: str, arms: list[int]) -> None:
        super().__init__(name)
        if not arms or any(int(a) != a or a < 0 for a in arms):
            raise ValueError(f"arms must be a non-empty list of arm indices >= 0, got {arms!r}")
        self.arms = [int(a) for a in arms]
        self._arms = np.asarray(self.arms, dtype=np.int64)

    def act_batch(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        contexts = np.asarray(observations).argmax(axis=1)
        if contexts.size and contexts.max() >= len(self.arms):
            raise ValueError(
                f"{self.name}: an observation names context {contexts.max()}, but this partner knows {len(self.arms)} contexts"
            )
        actions = self._arms[contexts]
        # A fixed partner has no fallback: playing a masked or missing arm would hide a mismatched env.
        masks = np.asarray(action_masks)
        if (actions >= masks.shape[1]).any() or not masks[np.arange(len(actions)), actions].all():
            raise ValueError(f"{self.name}: its arms {self.arms} are not all legal in this game (mask {masks[0].tolist()})")
        return actions

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return int(self.act_batch(np.asarray(observation)[None], np.asarray(action_mask)[None])[0])

    def params(self) -> dict[str, Any]:
        return {"arms": list(self.arms)}


@register_kind
class BanditMixedPartner(SampledPartner):
    """Pulls arm a in context c with probability `probs[c][a]`: a convention held with noise, or split between arms.

    It says what it draws from (`action_probs`), so the bandit's exact return and its
    best-response bound (`envs.best_response_return`) score it without sampling.
    """

    kind = "bandit_mixed"

    def __init__(self, name: str, probs: list[list[float]]) -> None:
        super().__init__(name)
        table = np.asarray(probs, dtype=np.float64)
        if table.ndim != 2 or table.size == 0 or not np.isfinite(table).all() or (table < 0).any():
            raise ValueError(f"probs must be a contexts x arms table of probabilities >= 0, got {probs!r}")
        if not np.allclose(table.sum(axis=1), 1.0, atol=1e-6):
            raise ValueError(f"each row of probs must sum to 1, got sums {table.sum(axis=1).round(6).tolist()}")
        self.probs = (table / table.sum(axis=1, keepdims=True)).tolist()
        self._table = np.asarray(self.probs)

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        contexts = np.asarray(observations).argmax(axis=1)
        masks = np.asarray(action_masks)
        if contexts.size and contexts.max() >= len(self._table):
            raise ValueError(
                f"{self.name}: an observation names context {contexts.max()}, but this partner knows {len(self._table)} contexts"
            )
        if masks.shape[1] != self._table.shape[1]:
            raise ValueError(f"{self.name}: it has {self._table.shape[1]} arms, the game {masks.shape[1]}")
        probs = self._table[contexts]
        # As the convention partner: mass on an illegal arm would hide a mismatched env.
        if (probs * (masks == 0)).any():
            raise ValueError(f"{self.name}: it pulls arms that are not legal in this game (mask {masks[0].tolist()})")
        return probs

    def params(self) -> dict[str, Any]:
        return {"probs": [list(row) for row in self.probs]}


def hand_designed_codes(symmetric: int, split: str) -> list[tuple[int, ...]]:
    """Return the 4 hand-designed conventions of a split: per symmetric context, 0 = low arm, 1 = high.

    Train partner k picks, in symmetric context j, bit 1 of k, bit 0 of k, or their XOR
    (cycling), so every context is split 2/2 between its two good arms, as the paper
    requires ("uniform over the optimal actions"). Test partners are the complements:
    also balanced, and disjoint from train whenever 2**symmetric allows (symmetric >= 3).
    """
    check_choice("symmetric", symmetric, range(PAPER_CONTEXTS + 1))
    check_choice("split", split, ["train", "test"])
    columns = [lambda k: (k >> 1) & 1, lambda k: k & 1, lambda k: ((k >> 1) ^ k) & 1]
    codes = [tuple(columns[j % 3](k) for j in range(symmetric)) for k in range(HAND_DESIGNED_PER_SPLIT)]
    if split == "test":
        codes = [tuple(1 - b for b in code) for code in codes]
    return codes


def convention_arms(code: tuple[int, ...], new_task: bool = False) -> list[int]:
    """Return the paper-bandit arm per context of a partner with convention `code`.

    Symmetric contexts `c < len(code)` pull `c` or `c + 4`; rule contexts pull the
    task's only good arm, which moves to `c + 4` on the new task. The convention is
    kept across tasks, as the paper's hand-designed partners do.
    """
    symmetric = len(code)
    return [
        c + PAPER_CONTEXTS * code[c] if c < symmetric else c + (PAPER_CONTEXTS if new_task else 0) for c in range(PAPER_CONTEXTS)
    ]


def hand_designed_partners(symmetric: int, split: str, new_task: bool = False) -> list[BanditConventionPartner]:
    """Return the paper's 4 hand-designed partners of `split` for the bandit with `symmetric` contexts."""
    return [
        BanditConventionPartner(f"hand-{split}-{k}", convention_arms(code, new_task))
        for k, code in enumerate(hand_designed_codes(symmetric, split))
    ]


def random_convention_partners(prizes: np.ndarray, n: int, seed: int, prefix: str = "rand") -> list[BanditConventionPartner]:
    """Return `n` partners, each pulling a uniformly drawn good arm per context (seeded)."""
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    rng = np.random.default_rng(seed)
    good = good_arms(np.asarray(prizes))
    return [BanditConventionPartner(f"{prefix}-{i}", [int(rng.choice(arms)) for arms in good]) for i in range(n)]


assert PAPER_ARMS == 2 * PAPER_CONTEXTS  # convention_arms relies on the high arm being c + 4


def bandit_hand(symmetric: int, new_task: bool) -> Population:
    """The paper's 4 + 4 hand-designed bandit partners; the new-task variant keeps their conventions."""
    return from_partners(
        f"bandit-s{symmetric}-hand{task_suffix(new_task)}",
        "bandit",
        {"symmetric": symmetric, "new_task": new_task},
        hand_designed_partners(symmetric, "train", new_task),
        hand_designed_partners(symmetric, "test", new_task),
        description="hand-designed: a fixed good arm per context, balanced over the good arms",
    )


def bandit_random(symmetric: int, n: int = RANDOM_PER_SPLIT, seed: int = 0) -> Population:
    """`n` + `n` partners each pulling a uniformly drawn good arm per context (seeded)."""
    prizes = paper_prizes(symmetric)
    return from_partners(
        f"bandit-s{symmetric}-random",
        "bandit",
        {"symmetric": symmetric},
        random_convention_partners(prizes, n, seed, prefix="rand-train"),
        random_convention_partners(prizes, n, seed + 1, prefix="rand-test"),
        description=f"random conventions: a uniformly drawn good arm per context (seeds {seed}, {seed + 1})",
    )


for _m in range(PAPER_CONTEXTS + 1):
    for _new in (False, True):
        register_builtin(f"bandit-s{_m}-hand{task_suffix(_new)}", partial(bandit_hand, _m, _new))
for _m in range(PAPER_CONTEXTS + 1):
    register_builtin(f"bandit-s{_m}-random", partial(bandit_random, _m))
