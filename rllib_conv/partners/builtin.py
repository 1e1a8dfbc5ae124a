"""The built-in partner populations (the paper's hand-designed and user-study partners)."""

from __future__ import annotations

from functools import partial

from rllib_conv.envs.bandit import PAPER_CONTEXTS, paper_prizes
from rllib_conv.partners.bandit import (
    hand_designed_partners,
    random_convention_partners,
)
from rllib_conv.partners.blocks import (
    TEST_PERMUTATIONS,
    TRAIN_PERMUTATIONS,
    PermutationPartner,
)
from rllib_conv.partners.hanabi import HanabiRulePartner, RandomLegalPartner
from rllib_conv.partners.population import Population, from_partners, register_builtin
from rllib_conv.partners.user_study import load_user_study, user_study_partners

# Pairs 1-12 train, 13-23 test: both participants of a pair stay on one side of the split.
USER_STUDY_TRAIN_PAIRS = range(1, 13)
RANDOM_PER_SPLIT = 10


def _task_suffix(new_task: bool) -> str:
    return "-newtask" if new_task else ""


def bandit_hand(symmetric: int, new_task: bool) -> Population:
    """The paper's 4 + 4 hand-designed bandit partners; the new-task variant keeps their conventions."""
    return from_partners(
        f"bandit-s{symmetric}-hand{_task_suffix(new_task)}",
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


def bandit_user_study(new_task: bool) -> Population:
    """One partner per study participant (try-5 choices); Train task, or Test with `new_task`."""
    df = load_user_study()
    task = "test" if new_task else "train"
    test_pairs = sorted(set(df["pair"]) - set(USER_STUDY_TRAIN_PAIRS))
    train = user_study_partners(task, df, pairs=USER_STUDY_TRAIN_PAIRS)
    test = user_study_partners(task, df, pairs=test_pairs)
    return from_partners(
        f"bandit-user-study{_task_suffix(new_task)}",
        "bandit",
        {"task": "user_study", "new_task": new_task},
        train,
        test,
        description="user study participants' try-5 conventions; pairs 1-12 train, 13-23 test",
    )


def blocks_permutations(new_task: bool) -> Population:
    """The 9 derangement partners (P2): 3 train, 6 test, as in the paper."""
    return from_partners(
        f"blocks-perm{_task_suffix(new_task)}",
        "blocks",
        {"new_task": new_task},
        [PermutationPartner(f"perm-{''.join(map(str, p))}", list(p)) for p in TRAIN_PERMUTATIONS],
        [PermutationPartner(f"perm-{''.join(map(str, p))}", list(p)) for p in TEST_PERMUTATIONS],
        description="P2 places blue at perm[red's cell after move 1], then passes",
    )


def hanabi_scripted() -> Population:
    """A rule-following Hanabi partner (train) and a uniformly random legal one (test)."""
    return from_partners(
        "hanabi-scripted",
        "hanabi",
        {},
        [HanabiRulePartner("rule")],
        [RandomLegalPartner("random")],
        description="scripted Hanabi players (self-play partners come from `rllib-conv partners train`)",
    )


for _m in range(PAPER_CONTEXTS + 1):
    for _new in (False, True):
        register_builtin(f"bandit-s{_m}-hand{_task_suffix(_new)}", partial(bandit_hand, _m, _new))
for _m in range(PAPER_CONTEXTS + 1):
    register_builtin(f"bandit-s{_m}-random", partial(bandit_random, _m))
for _new in (False, True):
    register_builtin(f"bandit-user-study{_task_suffix(_new)}", partial(bandit_user_study, _new))
    register_builtin(f"blocks-perm{_task_suffix(_new)}", partial(blocks_permutations, _new))
register_builtin("hanabi-scripted", hanabi_scripted)
