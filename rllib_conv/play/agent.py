"""The agent a person plays with: a trained ego's task module plus a partner module learnt from that person.

The policy is the paper's product of modules (Section 4), pi(a|s) ∝ g_t(a|s) * g_p(a|s):

- `g_t`, the **prior**, is the trained ego's task module: its estimate of the marginal best
  response over partners (`evaluate.task_probs`; the single network for BaselineAgg/MAML
  runs). It carries the rules of the task and stays fixed. A fresh partner module in the
  paper starts near uniform, so before any try with a person the agent plays `g_t` itself.
- `g_p`, the **partner module for this person**, is a table of logits `h[s]` (one row per
  observed state s, zero when unseen), so pi(.|s) = softmax(log g_t(.|s) + h[s]).

**Adaptation rule.** After each try (bandit) or game (blocks) the game says, in hindsight,
which action would have been the best response to what the person did in which state (the
"hindsight targets"): on the bandit, the arm the person pulled, in that context. For each
target (s, a*) the partner module takes one gradient step, step size eta (default 3), on
the cross-entropy -log pi(a*|s) with the task module frozen:

    h[s] <- h[s] + eta * (onehot(a*) - pi(.|s))

This is the supervised analogue of the paper's adaptation (a new partner module trained on
the new partner, task module frozen), one step per observation. Known answers: with
g_t uniform over the two good arms of a symmetric context, one observed choice moves the
agent to that arm with probability sigmoid(eta) = 0.953 (eta = 3), so a consistent person
is matched from the second try on (first try: 1/2); with a uniform prior over k legal
actions it is e^eta / (e^eta + k - 1) (0.87 for 4 arms). Because the step shrinks as pi(a*)
nears 1, h saturates: a convention never overrides a rule by much (an arm the task module
gives ~0 keeps ~0 unless the person insists on it try after try).

The table is keyed by the observation, so it carries over between tasks exactly where the
observation is the same: the bandit's Test task shows the same context one-hots, so a
person's Train-C convention is reused on Test-C (same good arms; after 5 Train-C tries the
first Test-C try matches with probability ~0.98), while on Test-B the new task module's rules
win over the stale convention (the paper's zero-shot coordination with the same partner on a
new task).

Hindsight targets per game (`bandit_targets`, `blocks_p1_targets`, `blocks_p2_targets`):
- bandit, either seat (both see the context): (context, the person's arm).
- blocks, agent = P1 (the trained ego's seat): the person's first blue placement b answered
  red on cell c, so for every goal with blue on b, "red on c at move 0" is the best signal.
- blocks, agent = P2 (the person took the ego's seat P1): no trained P2 exists, so the agent
  is a responder whose prior (`responder_prior`) puts blue on a cell without red at move 1
  and passes otherwise; its target is (red's cell after move 0 -> the blue goal), learnt
  when the goal is revealed at the end of the game.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from rllib_conv.envs.bandit import oracle_marginals
from rllib_conv.envs.blocks import (
    BLUE,
    NUM_CELLS,
    PASS,
    RED,
    apply_move,
    block_cell,
    decode_observation,
    encode_observation,
)
from rllib_conv.envs.blocks import NUM_ACTIONS as BLOCKS_ACTIONS

# obs [B, obs_dim] float32, mask [B, A] int8 -> action probabilities [B, A].
Prior = Callable[[np.ndarray, np.ndarray], np.ndarray]
# One hindsight target: (observation, action mask, best-response action).
Target = tuple[np.ndarray, np.ndarray, int]

DEFAULT_STEP_SIZE = 3.0
# Floor on the prior before its log: a task module's ~0 must stay finite so that a person
# who insists on an action can still (slowly) pull the agent there.
MIN_PROB = 1e-6


def legal_renormalised(probs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    probs = np.asarray(probs, dtype=np.float64) * (np.asarray(mask) > 0)
    total = probs.sum(axis=-1, keepdims=True)
    # A prior that gives no mass to any legal action falls back to uniform over legal ones.
    uniform = (np.asarray(mask) > 0) / np.maximum((np.asarray(mask) > 0).sum(axis=-1, keepdims=True), 1)
    return np.where(total > 0, probs / np.where(total > 0, total, 1.0), uniform)


def uniform_prior(obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Uniform over the legal actions: a task module that knows no rules."""
    return legal_renormalised(np.ones(np.shape(mask)), mask)


def bandit_oracle_prior(prizes: np.ndarray) -> Prior:
    """The true marginals of a bandit task: uniform over each context's good arms (the paper's oracle task module)."""
    marginals = oracle_marginals(np.asarray(prizes))

    def prior(obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
        contexts = np.asarray(obs).argmax(axis=-1)
        return legal_renormalised(marginals[contexts], mask)

    return prior


def responder_prior(obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Blocks P2 without a trained module: at move 1 blue on a cell without red (uniform), else pass."""
    out = np.zeros(np.shape(mask), dtype=np.float64)
    for i, o in enumerate(np.asarray(obs)):
        d = decode_observation(o)
        if d["move"] == 1:
            free = [c for c in range(NUM_CELLS) if d["grid"][c] != RED]
            out[i, free] = 1.0 / len(free)
        else:
            out[i, PASS] = 1.0
    return legal_renormalised(out, mask)


class PartnerTable:
    """The partner module for one person: logits `h[s]` added to the task module's, per observation s."""

    def __init__(self, step_size: float = DEFAULT_STEP_SIZE) -> None:
        if not (isinstance(step_size, (int, float)) and math.isfinite(step_size) and step_size > 0):
            raise ValueError(f"step_size must be a positive number, got {step_size!r}")
        self.step_size = float(step_size)
        self._h: dict[bytes, np.ndarray] = {}

    @staticmethod
    def key(obs: np.ndarray) -> bytes:
        """The table key of one observation vector (its float32 bytes)."""
        return np.asarray(obs, dtype=np.float32).tobytes()

    def logits(self, obs: np.ndarray, num_actions: int) -> np.ndarray:
        """This person's logits for `obs` (zeros for a state never updated)."""
        h = self._h.get(self.key(obs))
        return np.zeros(num_actions) if h is None else h.copy()

    def update(self, obs: np.ndarray, policy: np.ndarray, target: int) -> None:
        """One cross-entropy gradient step toward `target` given the current `policy` at `obs`."""
        grad = -np.asarray(policy, dtype=np.float64)
        grad[target] += 1.0
        key = self.key(obs)
        self._h[key] = self._h.get(key, np.zeros(len(grad))) + self.step_size * grad

    def __len__(self) -> int:
        return len(self._h)


class AdaptiveAgent:
    """Plays pi(.|s) ∝ prior(.|s) * exp(h[s]) and updates `h` from hindsight targets (module docstring).

    `prior` can be replaced between tries (the bandit's Test task gets its own task module)
    while the partner table, the conventions formed with this person, is kept. `greedy`
    plays the most likely action (ties broken at random) instead of sampling.
    """

    def __init__(
        self, prior: Prior, step_size: float = DEFAULT_STEP_SIZE, greedy: bool = False, seed: int | list[int] | None = None
    ) -> None:
        self.prior = prior
        self.partner = PartnerTable(step_size)
        self.greedy = bool(greedy)
        self._rng = np.random.default_rng(seed)

    def policy(self, obs: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The agent's action probabilities at one observation (legal actions only)."""
        obs = np.asarray(obs, dtype=np.float32)
        mask = np.asarray(mask)
        legal = mask > 0
        if not legal.any():
            raise ValueError("the action mask allows no action")
        prior = self.prior(obs[None], mask[None])[0]
        logits = np.log(np.maximum(prior, MIN_PROB)) + self.partner.logits(obs, len(mask))
        logits = np.where(legal, logits, -np.inf)
        z = np.exp(logits - logits[legal].max())
        return z / z.sum()

    def act(self, obs: np.ndarray, mask: np.ndarray) -> int:
        """Sample (or, if greedy, pick the best of) the agent's action at one observation."""
        probs = self.policy(obs, mask)
        if self.greedy:
            best = np.flatnonzero(probs >= probs.max() - 1e-12)
            return int(self._rng.choice(best))
        return int(self._rng.choice(len(probs), p=probs))

    def learn(self, targets: list[Target]) -> None:
        """Apply the adaptation rule to each hindsight target (observation, mask, best action) in turn."""
        for obs, mask, target in targets:
            if not (0 <= int(target) < len(mask)) or not mask[int(target)]:
                raise ValueError(f"hindsight target {target!r} is not a legal action (mask {np.asarray(mask).tolist()})")
            self.partner.update(obs, self.policy(obs, mask), int(target))

    def watch(self, moves: list[Target]) -> None:
        """The person's own moves (their observation, mask, action): the paper's agent learns from hindsight targets alone, so nothing here."""


# --- hindsight targets -----------------------------------------------------------------


def bandit_observation(context: int, num_contexts: int) -> np.ndarray:
    """The bandit's observation of `context` (a one-hot vector), as both seats see it."""
    obs = np.zeros(num_contexts, dtype=np.float32)
    obs[context] = 1.0
    return obs


def bandit_targets(context: int, num_contexts: int, num_arms: int, person_arm: int) -> list[Target]:
    """Bandit: the best response to a person who pulled `person_arm` in `context` is that arm (0-based)."""
    return [(bandit_observation(context, num_contexts), np.ones(num_arms, dtype=np.int8), int(person_arm))]


def replay_grids(history: list[tuple[int, int]]) -> list[np.ndarray]:
    """Blocks: the working grid before each move of `history` ((player 1|2, action) pairs)."""
    grid = np.zeros(NUM_CELLS, dtype=np.int64)
    grids = []
    for player, action in history:
        grids.append(grid.copy())
        grid = apply_move(grid, RED if player == 1 else BLUE, action)
    return grids


def _goal_grid(red: int, blue: int) -> np.ndarray:
    goal = np.zeros(NUM_CELLS, dtype=np.int64)
    goal[red], goal[blue] = RED, BLUE
    return goal


def blocks_p1_targets(history: list[tuple[int, int]]) -> list[Target]:
    """Blocks, agent = P1: the person's first blue placement b answered red on c; signal b by red on c at move 0.

    Returns one target per goal with blue on b (3 goals), or none if the person never
    placed blue while red was on the grid.
    """
    for grid, (player, action) in zip(replay_grids(history), history):
        red = block_cell(grid, RED)
        if player == 2 and action < NUM_CELLS and red is not None:
            blue = action
            mask = np.ones(BLOCKS_ACTIONS, dtype=np.int8)
            empty = np.zeros(NUM_CELLS, dtype=np.int64)
            return [
                (encode_observation(_goal_grid(r, blue), empty, 0, sees_goal=True), mask, red)
                for r in range(NUM_CELLS)
                if r != blue
            ]
    return []


def blocks_p2_moves(history: list[tuple[int, int]]) -> list[Target]:
    """Blocks: P2's moves of `history` as P2 saw them (goal hidden, the grid, the move number), with its mask (every action)."""
    hidden = np.zeros(NUM_CELLS, dtype=np.int64)  # not shown: P2 does not see the goal
    mask = np.ones(BLOCKS_ACTIONS, dtype=np.int8)
    return [
        (encode_observation(hidden, grid, move, sees_goal=False), mask, int(action))
        for move, (grid, (player, action)) in enumerate(zip(replay_grids(history), history))
        if player == 2
    ]


def blocks_p2_targets(history: list[tuple[int, int]], goal: tuple[int, int]) -> list[Target]:
    """Blocks, agent = P2: after red's first move put it on c, blue belonged on the goal's blue cell."""
    if len(history) < 2:
        return []
    grid = replay_grids(history)[1]  # the grid P2 saw at move 1
    if block_cell(grid, RED) is None:
        return []
    obs = encode_observation(_goal_grid(*goal), grid, 1, sees_goal=False)  # P2 sees the goal hidden
    return [(obs, np.ones(BLOCKS_ACTIONS, dtype=np.int8), int(goal[1]))]
