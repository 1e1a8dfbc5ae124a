"""The user-study table: the CSV format of the paper's human-human study and of sessions recorded live.

23 pairs of people played the collaborative contextual bandit (3 contexts A, B, C x 4
arms; prize 1 when both pick the same good arm), 5 tries per context, first on the
Train task and then on the Test task. The appendix table records each pair's joint
action on try 1 and try 5; `analysis/data/user_study.csv` transcribes it, one row per
(pair, task, context, try), with the paper's 1-based arm numbers. The same format holds
sessions recorded live by `rllib-conv play`, which may hold any of the tries 1..5.

`load_user_study` reads and validates such a CSV and `first_try_scores` reproduces the
paper's bar chart (`fig:userstudy`); the study's two tasks (good arms per context) are
defined here too, since the table cannot be read without them. Partners built from the
table live in `rllib_conv.partners.user_study`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from rllib_conv.common.resources import user_study_csv

TASKS: tuple[str, ...] = ("train", "test")
CONTEXTS: tuple[str, ...] = ("A", "B", "C")
MAX_TRIES = 5
COLUMNS: tuple[str, ...] = ("pair", "task", "context", "try", "action_1", "action_2")

# 0-based good arms per context of the study's two tasks (the paper's Fig. 4 counts from 1).
USER_STUDY_GOOD_ARMS: dict[str, list[tuple[int, ...]]] = {
    "train": [(0,), (2, 3), (1, 3)],
    "test": [(2,), (0, 1), (1, 3)],
}
USER_STUDY_ARMS = 4
DEFAULT_PATH = user_study_csv()


def _line(index: int) -> int:
    """CSV line number of data row `index` (line 1 is the header)."""
    return index + 2


def _parse_ints(df: pd.DataFrame, column: str, low: int, high: int, what: str) -> pd.Series:
    """Return `df[column]` as int64, or raise naming the first row that is not an integer in [low, high]."""
    values = df[column]
    parsed = pd.to_numeric(values, errors="coerce")
    bad = parsed.isna() | (parsed != parsed.round()) | (parsed < low) | (parsed > high)
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise ValueError(
            f"user study CSV: column {column!r}, line {_line(i)}: expected {what} (an integer in {low}..{high}), "
            f"got {values.iloc[i]!r}"
        )
    return parsed.astype("int64")


def _check_choice(df: pd.DataFrame, column: str, allowed: tuple[str, ...]) -> None:
    """Raise naming the first row whose `column` is not one of `allowed`."""
    bad = ~df[column].isin(allowed)
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise ValueError(
            f"user study CSV: column {column!r}, line {_line(i)}: expected one of {list(allowed)}, got {df[column].iloc[i]!r}"
        )


def load_user_study(path: str | Path | None = None) -> pd.DataFrame:
    """Read and validate a user-study CSV; return one row per (pair, task, context, try).

    `path` defaults to the shipped `analysis/data/user_study.csv` (the paper's table). The file must have the columns `pair, task, context, try, action_1,
    action_2` (extra columns are kept): `pair` a positive integer, `task` in
    {train, test}, `context` in {A, B, C}, `try` in 1..5, actions the 1-based arms
    1..4, and no (pair, task, context, try) twice. Any violation raises ValueError
    naming the column, the CSV line and what was expected.

    The returned frame has those columns (integers as int64) plus `arm_1`, `arm_2`
    (0-based arms) and `coordinated` (1 when both picked the same arm and it is a
    good arm of that task and context, i.e. the prize of that try; else 0).
    """
    path = DEFAULT_PATH if path is None else Path(path)
    # Read everything as text so that "2.5", "x" or an empty cell is reported, not silently coerced.
    raw = pd.read_csv(path, dtype=str, keep_default_na=False)
    raw.columns = [str(c).strip() for c in raw.columns]
    missing = [c for c in COLUMNS if c not in raw.columns]
    if missing:
        raise ValueError(
            f"user study CSV {str(path)!r}: missing column(s) {missing}; expected columns {list(COLUMNS)}, "
            f"found {list(raw.columns)}"
        )
    df = raw.copy()
    for column in COLUMNS:
        df[column] = df[column].astype(str).str.strip()

    df["pair"] = _parse_ints(df, "pair", 1, np.iinfo(np.int64).max, "a pair ID")
    _check_choice(df, "task", TASKS)
    _check_choice(df, "context", CONTEXTS)
    df["try"] = _parse_ints(df, "try", 1, MAX_TRIES, "a try number")
    df["action_1"] = _parse_ints(df, "action_1", 1, USER_STUDY_ARMS, "a 1-based arm")
    df["action_2"] = _parse_ints(df, "action_2", 1, USER_STUDY_ARMS, "a 1-based arm")

    key = ["pair", "task", "context", "try"]
    dup = df.duplicated(subset=key, keep="first")
    if dup.any():
        i = int(np.flatnonzero(dup.to_numpy())[0])
        row = df.iloc[i]
        raise ValueError(
            f"user study CSV: line {_line(i)} repeats pair {row['pair']}, task {row['task']!r}, "
            f"context {row['context']!r}, try {row['try']}; expected each (pair, task, context, try) once"
        )

    df["arm_1"] = df["action_1"] - 1
    df["arm_2"] = df["action_2"] - 1
    good = [
        arm in USER_STUDY_GOOD_ARMS[task][CONTEXTS.index(context)]
        for arm, task, context in zip(df["arm_1"], df["task"], df["context"])
    ]
    df["coordinated"] = ((df["arm_1"] == df["arm_2"]) & np.asarray(good, dtype=bool)).astype("int64")
    return df


def first_try_scores(df: pd.DataFrame, exclude_pairs: Iterable[int] = (), ddof: int = 1) -> pd.DataFrame:
    """Return the first-try score per task and context, as in the paper's `fig:userstudy` bar chart.

    `df` is a frame from `load_user_study`; the pairs in `exclude_pairs` are left out. The
    result has one row per (task, context) present at try 1, ordered train A, B, C then
    test A, B, C, with columns `task`, `context`, `score` (mean of `coordinated` over
    pairs), `sem` (standard error of that mean: std with `ddof` over sqrt(n); NaN when
    n <= ddof), `n` (pairs) and `coordinated` (how many pairs coordinated).
    """
    if "coordinated" not in df.columns:
        raise ValueError("first_try_scores needs the `coordinated` column; pass a frame from load_user_study")
    first = df[(df["try"] == 1) & ~df["pair"].isin(set(exclude_pairs))]
    grouped = first.groupby(["task", "context"])["coordinated"]
    out = pd.DataFrame(
        {"score": grouped.mean(), "sem": grouped.sem(ddof=ddof), "n": grouped.size(), "coordinated": grouped.sum()}
    )
    # groupby sorts alphabetically ("test" before "train"); the paper reads train first.
    order = [(t, c) for t in TASKS for c in CONTEXTS if (t, c) in out.index]
    out = out.loc[order].reset_index()
    out[["n", "coordinated"]] = out[["n", "coordinated"]].astype("int64")
    return out[["task", "context", "score", "sem", "n", "coordinated"]]
