"""Partners built from the paper's user study: one fixed partner per participant, replaying their try-5 choices.

The paper's "partner policies derived from the data collected in our user study": each
participant's last try in each context is the convention the pair settled on. The table
and its format are in `rllib_conv.common.user_study_table`. The built-in populations
`bandit-user-study[-newtask]` are declared here.
"""

from __future__ import annotations

from functools import partial
from typing import Iterable

import pandas as pd

from rllib_conv.common.user_study_table import CONTEXTS, MAX_TRIES, TASKS, load_user_study
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.population import Population, from_partners, register_builtin, task_suffix

# Pairs 1-12 train, 13-23 test: both participants of a pair stay on one side of the split.
USER_STUDY_TRAIN_PAIRS = range(1, 13)


def user_study_partners(
    task: str = "train", df: pd.DataFrame | None = None, pairs: Iterable[int] | None = None
) -> list[BanditConventionPartner]:
    """Return one fixed partner per study participant, playing their try-5 arm of `task` in each context.

    `df` defaults to `load_user_study()`. Partners come ordered by pair, participant
    1 before 2, named like "us-p07-1" (pair 7, participant 1); the paper's table gives
    46. `pairs` keeps only those pair IDs. Raises ValueError for an unknown task or a pair lacking try 5 in some context.
    """
    if task not in TASKS:
        raise ValueError(f"task must be one of {list(TASKS)}, got {task!r}")
    if df is None:
        df = load_user_study()
    # The last try is the convention a pair settled on; that is what a partner policy should replay.
    last = df[(df["task"] == task) & (df["try"] == MAX_TRIES)]
    partners: list[BanditConventionPartner] = []
    wanted = None if pairs is None else set(pairs)
    for pair in sorted(df.loc[df["task"] == task, "pair"].unique()):
        if wanted is not None and pair not in wanted:
            continue
        rows = last[last["pair"] == pair].set_index("context")
        lacking = [c for c in CONTEXTS if c not in rows.index]
        if lacking:
            raise ValueError(f"pair {pair}, task {task!r}: no try {MAX_TRIES} for context(s) {lacking}")
        for participant in (1, 2):
            arms = [int(rows.at[c, f"arm_{participant}"]) for c in CONTEXTS]
            partners.append(BanditConventionPartner(name=f"us-p{int(pair):02d}-{participant}", arms=arms))
    return partners


def bandit_user_study(new_task: bool) -> Population:
    """One partner per study participant (try-5 choices); Train task, or Test with `new_task`."""
    df = load_user_study()
    task = "test" if new_task else "train"
    test_pairs = sorted(set(df["pair"]) - set(USER_STUDY_TRAIN_PAIRS))
    train = user_study_partners(task, df, pairs=USER_STUDY_TRAIN_PAIRS)
    test = user_study_partners(task, df, pairs=test_pairs)
    return from_partners(
        f"bandit-user-study{task_suffix(new_task)}",
        "bandit",
        {"task": "user_study", "new_task": new_task},
        train,
        test,
        description="user study participants' try-5 conventions; pairs 1-12 train, 13-23 test",
    )


for _new in (False, True):
    register_builtin(f"bandit-user-study{task_suffix(_new)}", partial(bandit_user_study, _new))
