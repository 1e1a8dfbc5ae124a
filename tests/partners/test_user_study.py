"""The user-study CSV (the paper's appendix table), its loader, first-try scores and partners."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rllib_conv.common.user_study_table import CONTEXTS, DEFAULT_PATH, USER_STUDY_GOOD_ARMS, first_try_scores, load_user_study
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.kinds import partner_from_spec
from rllib_conv.partners.user_study import user_study_partners

COLUMNS = ["pair", "task", "context", "try", "action_1", "action_2"]


@pytest.fixture(scope="module")
def df() -> pd.DataFrame:
    return load_user_study()


def cell(df: pd.DataFrame, pair: int, task: str, context: str, try_: int) -> tuple[int, int]:
    row = df[(df["pair"] == pair) & (df["task"] == task) & (df["context"] == context) & (df["try"] == try_)]
    assert len(row) == 1
    return int(row["action_1"].iloc[0]), int(row["action_2"].iloc[0])


def one_hot(context: int) -> np.ndarray:
    obs = np.zeros(len(CONTEXTS), dtype=np.float32)
    obs[context] = 1.0
    return obs


ALL_ARMS = np.ones(4, dtype=np.int8)


# --- the CSV ---------------------------------------------------------------------------


def test_csv_shape_and_values(df: pd.DataFrame) -> None:
    assert DEFAULT_PATH.is_file()
    assert list(pd.read_csv(DEFAULT_PATH).columns) == COLUMNS
    assert len(df) == 23 * 2 * 3 * 2 == 276
    assert sorted(df["pair"].unique()) == list(range(1, 24))
    assert set(df["task"]) == {"train", "test"}
    assert set(df["context"]) == {"A", "B", "C"}
    assert set(df["try"]) == {1, 5}
    assert df["action_1"].between(1, 4).all() and df["action_2"].between(1, 4).all()
    assert (df["arm_1"] == df["action_1"] - 1).all() and (df["arm_2"] == df["action_2"] - 1).all()
    assert not df.duplicated(["pair", "task", "context", "try"]).any()
    assert (df.groupby("pair").size() == 12).all()


@pytest.mark.parametrize(
    ("pair", "task", "context", "try_", "actions"),
    [
        (10, "train", "C", 5, (2, 4)),
        (3, "train", "B", 1, (4, 3)),
        (10, "train", "A", 1, (1, 2)),
        (7, "test", "A", 1, (1, 1)),  # arm 1 is Train-A's good arm, not Test-A's
        (10, "test", "A", 1, (1, 3)),
        (10, "test", "B", 1, (4, 2)),
        (10, "test", "B", 5, (2, 1)),
        (18, "test", "C", 1, (2, 4)),
        (16, "train", "C", 1, (4, 3)),
        (20, "test", "B", 1, (2, 3)),
        (5, "test", "C", 5, (4, 4)),
        (23, "train", "C", 1, (4, 2)),
    ],
)
def test_spot_cells(df: pd.DataFrame, pair: int, task: str, context: str, try_: int, actions: tuple[int, int]) -> None:
    assert cell(df, pair, task, context, try_) == actions


def test_good_arms_match_the_paper() -> None:
    # Paper's figure, 1-based: Train A {1}, B {3,4}, C {2,4}; Test A {3}, B {1,2}, C {2,4}.
    one_based = {task: [{a + 1 for a in arms} for arms in ctxs] for task, ctxs in USER_STUDY_GOOD_ARMS.items()}
    assert one_based == {"train": [{1}, {3, 4}, {2, 4}], "test": [{3}, {1, 2}, {2, 4}]}


# --- first-try scores --------------------------------------------------------------------

# Counted by hand from the appendix table of the .tex (try-1 cells that are k/k with k good).
HAND_COUNTED_FIRST_TRY = {
    ("train", "A"): 22 / 23,  # all pairs except pair 10 (1/2)
    ("train", "B"): 9 / 23,  # pairs 1, 2, 4, 5, 6, 8, 9, 11, 17; pair 10 is 2/2 (arm 2 not good)
    ("train", "C"): 13 / 23,  # pairs 1, 2, 4, 5, 6, 7, 8, 9, 11, 15, 18, 20, 22; pair 10 is 3/3 (not good)
    ("test", "A"): 21 / 23,  # all pairs except 7 (1/1, arm 1 not good) and 10 (1/3)
    ("test", "B"): 11 / 23,  # pairs 4, 6, 8, 9, 11, 12, 14, 16, 17, 19, 23
    ("test", "C"): 22 / 23,  # all pairs except pair 18 (2/4)
}


def test_first_try_scores_match_hand_counts(df: pd.DataFrame) -> None:
    scores = first_try_scores(df)
    assert list(zip(scores["task"], scores["context"])) == [(t, c) for t in ("train", "test") for c in "ABC"]
    assert (scores["n"] == 23).all()
    for task, context, score in zip(scores["task"], scores["context"], scores["score"]):
        assert score == pytest.approx(HAND_COUNTED_FIRST_TRY[(task, context)])


def test_first_try_sem_is_sample_std_over_sqrt_n(df: pd.DataFrame) -> None:
    scores = first_try_scores(df).set_index(["task", "context"])
    p = 9 / 23
    expected = np.sqrt(p * (1 - p) * 23 / 22) / np.sqrt(23)  # Bernoulli sample std, ddof=1
    assert scores.loc[("train", "B"), "sem"] == pytest.approx(expected)


def test_try_five_coordination(df: pd.DataFrame) -> None:
    last = df[df["try"] == 5]
    failed = last[last["coordinated"] == 0][["pair", "task", "context"]].values.tolist()
    # Only pair 10 fails on try 5: Train-C 2/4, Test-B 2/1, Test-C 2/4.
    assert sorted(failed) == sorted([[10, "train", "C"], [10, "test", "B"], [10, "test", "C"]])


# --- partners ----------------------------------------------------------------------------


@pytest.mark.parametrize("task", ["train", "test"])
def test_partners_play_their_try_five_arm(df: pd.DataFrame, task: str) -> None:
    partners = user_study_partners(task, df)
    assert len(partners) == 46
    assert partners[0].name == "us-p01-1" and partners[-1].name == "us-p23-2"
    assert len({p.name for p in partners}) == 46
    for p in partners:
        pair, participant = int(p.name[4:6]), int(p.name[-1])
        for k, context in enumerate(CONTEXTS):
            action = cell(df, pair, task, context, 5)[participant - 1]
            assert p.act(one_hot(k), ALL_ARMS) == action - 1


def test_named_partners(df: pd.DataFrame) -> None:
    by_name = {p.name: p for p in user_study_partners("train", df)}
    # Pair 10 train try 5: A 1/1, B 4/4, C 2/4 (1-based).
    assert by_name["us-p10-1"].arms == [0, 3, 1]
    assert by_name["us-p10-2"].arms == [0, 3, 3]
    # Pair 5 train try 5: A 1/1, B 4/4, C 4/4.
    assert by_name["us-p05-1"].arms == by_name["us-p05-2"].arms == [0, 3, 3]


@pytest.mark.parametrize("task", ["train", "test"])
def test_coordinated_pairs_play_good_arms(df: pd.DataFrame, task: str) -> None:
    last = df[(df["task"] == task) & (df["try"] == 5)]
    coordinated_pairs = set(last.groupby("pair")["coordinated"].min().loc[lambda s: s == 1].index)
    assert coordinated_pairs == set(range(1, 24)) - {10}
    for p in user_study_partners(task, df):
        if int(p.name[4:6]) in coordinated_pairs:
            for k, arm in enumerate(p.arms):
                assert arm in USER_STUDY_GOOD_ARMS[task][k], (p.name, k, arm)


def test_spec_round_trip(df: pd.DataFrame) -> None:
    for p in user_study_partners("train", df)[:6]:
        spec = p.to_spec()
        assert spec["kind"] == "bandit_convention"
        q = partner_from_spec(spec)
        assert isinstance(q, BanditConventionPartner) and q.name == p.name and q.params() == p.params()
        for k in range(len(CONTEXTS)):
            assert q.act(one_hot(k), ALL_ARMS) == p.act(one_hot(k), ALL_ARMS)


# --- loader validation -------------------------------------------------------------------


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "study.csv"
    path.write_text(text)
    return path


HEADER = "pair,task,context,try,action_1,action_2\n"


def test_loader_accepts_any_tries_and_extra_columns(tmp_path: Path) -> None:
    # A live session records every try; Test-B's good arms are 1 and 2 (1-based).
    actions = ["2/3", "1/2", "3/3", "2/1", "2/2"]
    rows = "".join(f"1,test,B,{t},{a.replace('/', ',')},x\n" for t, a in enumerate(actions, start=1))
    df = load_user_study(write(tmp_path, HEADER.rstrip("\n") + ",note\n" + rows))
    assert df["try"].tolist() == [1, 2, 3, 4, 5]
    assert df["coordinated"].tolist() == [0, 0, 0, 0, 1]  # 3/3 agrees on a bad arm; only 2/2 wins
    assert "note" in df.columns


def test_loader_rejects_missing_column(tmp_path: Path) -> None:
    path = write(tmp_path, "pair,task,context,try,action_1\n1,train,A,1,1\n")
    with pytest.raises(ValueError, match=r"missing column\(s\) \['action_2'\]"):
        load_user_study(path)


@pytest.mark.parametrize(
    ("row", "pattern"),
    [
        ("1,train,A,1,5,1", r"column 'action_1', line 3: expected a 1-based arm .*1\.\.4.*'5'"),
        ("1,train,A,1,1,0", r"column 'action_2', line 3: expected a 1-based arm"),
        ("1,train,A,1,1.5,1", r"column 'action_1', line 3"),
        ("1,valid,A,1,1,1", r"column 'task', line 3: expected one of \['train', 'test'\], got 'valid'"),
        ("1,train,D,1,1,1", r"column 'context', line 3"),
        ("1,train,A,6,1,1", r"column 'try', line 3: expected a try number"),
        ("0,train,A,1,1,1", r"column 'pair', line 3"),
        ("1,train,A,1,,1", r"column 'action_1', line 3"),
        ("1,train,A,1,1,1", r"line 3 repeats pair 1, task 'train', context 'A', try 1"),
    ],
)
def test_loader_rejects_bad_values(tmp_path: Path, row: str, pattern: str) -> None:
    path = write(tmp_path, HEADER + "1,train,A,1,1,1\n" + row + "\n")
    with pytest.raises(ValueError, match=pattern):
        load_user_study(path)


def test_user_study_partners_needs_try_five(tmp_path: Path) -> None:
    df = load_user_study(write(tmp_path, HEADER + "1,train,A,5,1,1\n1,train,B,5,3,3\n1,train,C,1,2,2\n"))
    with pytest.raises(ValueError, match=r"pair 1, task 'train': no try 5 for context\(s\) \['C'\]"):
        user_study_partners("train", df)
    with pytest.raises(ValueError, match="task must be one of"):
        user_study_partners("valid", df)
