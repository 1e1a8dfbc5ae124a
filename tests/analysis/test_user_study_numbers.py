"""The user-study numbers against values counted by hand from `analysis/data/user_study.csv`."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest

from analysis import loaders, paper
from analysis.summaries import paper_figure_recipe, user_study_scores

# First tries (try == 1) counted by hand from the CSV: a pair scores when both actions are equal
# and a good arm of that task and context (1-based: Train A {1}, B {3,4}, C {2,4};
# Test A {3}, B {1,2}, C {2,4}). Pairs that did NOT score:
#   Train-A: 10 (1/2)                                  -> 22/23
#   Train-B: 3 7 10 12 13 14 15 16 18 19 20 21 22 23   -> 9/23   (10 is 2/2, arm 2 not good)
#   Train-C: 3 10 12 13 14 16 17 19 21 23              -> 13/23  (10 is 3/3, arm 3 not good)
#   Test-A:  7 (1/1, arm 1 not good), 10 (1/3)          -> 21/23
#   Test-B:  1 2 3 5 7 10 13 15 18 20 21 22            -> 11/23
#   Test-C:  18 (2/4)                                  -> 22/23  (10 is 2/2: it scores)
HAND_COUNTS = {("train", "A"): 22, ("train", "B"): 9, ("train", "C"): 13, ("test", "A"): 21, ("test", "B"): 11, ("test", "C"): 22}

# Without pair 10 (22 pairs): Train-A 22, Train-B 9, Train-C 13, Test-A 21, Test-B 11, Test-C 21
# (pair 10 scored only on Test-C). The paper's figure then shows Train-A and Test-A exchanged.
FIGURE_COUNTS = {
    ("train", "A"): 21,
    ("train", "B"): 9,
    ("train", "C"): 13,
    ("test", "A"): 22,
    ("test", "B"): 11,
    ("test", "C"): 21,
}


@pytest.fixture(scope="module")
def study():
    return loaders.load_user_study_csvs()


def test_first_try_scores_equal_hand_counts(study) -> None:
    scores = user_study_scores(study)
    assert [(r.task, r.context) for r in scores.itertuples()] == [(t, c) for t in ("train", "test") for c in "ABC"]
    for r in scores.itertuples():
        k = HAND_COUNTS[(r.task, r.context)]
        assert (r.coordinated, r.n) == (k, 23)
        assert r.score == pytest.approx(k / 23)
        p = k / 23
        assert r.sem == pytest.approx(math.sqrt(p * (1 - p) / 22))  # sample std (ddof=1) / sqrt(23)


def test_known_values_written_out(study) -> None:
    s = user_study_scores(study).set_index(["task", "context"])
    assert s.loc[("train", "B"), "score"] == pytest.approx(0.3913, abs=1e-4)
    assert s.loc[("test", "B"), "score"] == pytest.approx(0.4783, abs=1e-4)
    assert s.loc[("test", "C"), "score"] == pytest.approx(0.9565, abs=1e-4)
    assert s.loc[("train", "B"), "sem"] == pytest.approx(0.1041, abs=1e-4)


def test_paper_figure_recipe_gives_the_figure(study) -> None:
    fig = paper_figure_recipe(study).set_index(["task", "context"])
    for key, k in FIGURE_COUNTS.items():
        p = k / 22
        assert fig.loc[key, "n"] == 22 and fig.loc[key, "coordinated"] == k
        assert fig.loc[key, "score"] == pytest.approx(p)
        assert fig.loc[key, "sem"] == pytest.approx(math.sqrt(p * (1 - p) / 22))  # np.std (ddof=0) / sqrt(22)
    # ... and these are the paper's printed bars (pgfplots values, rounded as printed).
    printed = {
        ("train", "A"): (0.9545, 0.044),
        ("test", "A"): (1.0, 0.0),
        ("train", "B"): (0.4091, 0.10),
        ("test", "B"): (0.50, 0.11),
        ("train", "C"): (0.5909, 0.10),
        ("test", "C"): (0.9545, 0.044),
    }
    for key, (value, error) in printed.items():
        assert fig.loc[key, "score"] == pytest.approx(value, abs=5e-5)
        assert fig.loc[key, "sem"] == pytest.approx(error, abs=5e-3)
        assert paper.USER_STUDY_FIGURE[key].value == value and paper.USER_STUDY_FIGURE[key].error == error


def test_table_is_not_the_figure(study) -> None:
    # Straight from the table, Test-A is 21/23 = 0.913, not the figure's 1.
    s = user_study_scores(study).set_index(["task", "context"])
    assert s.loc[("test", "A"), "score"] == pytest.approx(21 / 23)
    assert abs(s.loc[("test", "A"), "score"] - paper.USER_STUDY_FIGURE[("test", "A")].value) > 0.08


def test_several_files_pool(study, tmp_path: Path) -> None:
    from rllib_conv.common.user_study_table import DEFAULT_PATH

    for name in ("a.csv", "b.csv"):
        shutil.copy(DEFAULT_PATH, tmp_path / name)
    pooled = user_study_scores(loaders.load_user_study_csvs(tmp_path)).set_index(["task", "context"])
    for key, k in HAND_COUNTS.items():
        assert pooled.loc[key, "n"] == 46 and pooled.loc[key, "coordinated"] == 2 * k


def test_live_session_counts_only_first_try(tmp_path: Path) -> None:
    # One recorded pair, every try of Test-B (good arms 1, 2): tries 2..5 must not count.
    rows = "".join(f"1,test,B,{t},{a},{b}\n" for t, (a, b) in enumerate([(2, 3), (1, 1), (1, 1), (1, 1), (1, 1)], start=1))
    (tmp_path / "live.csv").write_text("pair,task,context,try,action_1,action_2\n" + rows)
    s = user_study_scores(loaders.load_user_study_csvs(tmp_path / "live.csv"))
    assert len(s) == 1 and s.iloc[0]["score"] == 0.0 and s.iloc[0]["n"] == 1 and math.isnan(s.iloc[0]["sem"])
