"""Loaders on the fixture run folder (a subset of a real quick bandit reproduction)."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from analysis import loaders

FIXTURE = Path(__file__).parent / "fixtures" / "repro"
GAME = FIXTURE / "bandit"
S2_MODULAR = "bandit-s2-hand__modular-lam0.5"


@pytest.fixture()
def copy(tmp_path: Path) -> Path:
    """A writable copy of the fixture root."""
    target = tmp_path / "repro"
    shutil.copytree(FIXTURE, target)
    return target


def test_game_dirs_from_root_or_game_folder(tmp_path: Path) -> None:
    assert loaders.game_dirs(FIXTURE) == [GAME]
    assert loaders.game_dirs(GAME) == [GAME]
    assert loaders.game_dirs(tmp_path) == []
    assert {k: loaders.read_plan(GAME)[k] for k in ("game", "seeds", "quick")} == {"game": "bandit", "seeds": [0], "quick": True}


def test_stage_times() -> None:
    st = loaders.load_stage_times(FIXTURE).set_index("stage")
    assert list(st.index) == list(loaders.STAGES)
    # Every stage of the bandit's plan is done; it has no held-out evaluation.
    assert st["done"].drop(["heldout", "evaluate"]).all() and not st.loc[["heldout", "evaluate"], "expected"].any()
    # The .done markers read "65.0 s", "30.8 s", "104.4 s", "0.0 s", "0.1 s".
    assert st.loc["train", "seconds"] == 65.0 and st.loc["adapt", "seconds"] == 30.8 and st.loc["zeroshot", "seconds"] == 104.4


def test_expected_stages() -> None:
    assert loaders.expected_stages("bandit") == tuple(
        s for s in loaders.STAGES if s not in ("heldout", "evaluate")
    )  # older than those
    assert loaders.expected_stages("blocks", quick=True) == ("selfplay", "train", "adapt", "marginals")
    assert loaders.expected_stages("hanabi") == ("selfplay", "train", "adapt")


def test_stage_times_missing_marker(copy: Path) -> None:
    (copy / "bandit" / "zeroshot.done").unlink()
    st = loaders.load_stage_times(copy).set_index("stage")
    assert not st.loc["zeroshot", "done"] and st.loc["zeroshot", "expected"] and math.isnan(st.loc["zeroshot", "seconds"])
    assert st.loc["train", "done"]


def test_stage_done_only_when_its_marker_covers_the_plan(copy: Path) -> None:
    # A 5-seed plan over a folder whose zero-shot marker a stopped 5-seed run left at the 3-seed items.
    game = copy / "bandit"
    plan = {
        "game": "bandit",
        "seeds": [0, 1, 2, 3, 4],
        "quick": False,
        "stages": ["train", "zeroshot"],
        "items": {"train": ["a seeds=0,1,2,3,4"], "zeroshot": ["z seeds=0,1,2,3,4"]},
    }
    (game / "plan.json").write_text(json.dumps(plan))
    (game / "train.done").write_text("10.0 s\na seeds=0,1,2\na seeds=0,1,2,3,4\n")
    (game / "zeroshot.done").write_text("7.5 s\nz seeds=0,1,2\n")
    st = loaders.load_stage_times(copy).set_index("stage")
    assert st.loc["train", "done"] and st.loc["train", "seconds"] == 10.0
    assert not st.loc["zeroshot", "done"] and st.loc["zeroshot", "expected"] and st.loc["zeroshot", "seconds"] == 7.5
    (game / "zeroshot.done").write_text("")  # not a marker this code wrote
    st = loaders.load_stage_times(copy).set_index("stage")
    assert not st.loc["zeroshot", "done"] and math.isnan(st.loc["zeroshot", "seconds"])


def test_training_one_row_per_trial_and_iteration() -> None:
    tr = loaders.load_training(FIXTURE)
    # 4 trained-ego trials x 8 iterations; runs/adapt-* (Tune internals) is ignored.
    assert len(tr) == 32
    assert tr["run"].nunique() == 4
    assert set(tr["experiment"]) == {
        "bandit-s1-hand__modular-lam0.5",
        "bandit-s1-hand__no_task_logits",
        "bandit-s2-hand__agg",
        S2_MODULAR,
    }
    s2 = tr[tr["experiment"] == S2_MODULAR].sort_values("training_iteration")
    assert s2["training_iteration"].tolist() == list(range(1, 9))
    assert s2["steps"].tolist() == [256 * i for i in range(1, 9)]  # the env_steps column
    first = s2.iloc[0]
    assert (first["game"], first["population"], first["label"], first["method"], first["lam"], first["seed"]) == (
        "bandit",
        "bandit-s2-hand",
        "modular-lam0.5",
        "modular",
        0.5,
        0,
    )
    assert first["z_dim"] == 30  # z_dim null in config.yaml: z is the last hidden layer (hidden 30)
    assert s2["return_mean"].iloc[-1] == pytest.approx(0.703125)  # progress.csv, last line
    assert "return/hand-train-3" in tr.columns and "marginal_reg" in tr.columns


def test_training_restored_trial_keeps_last_log(copy: Path) -> None:
    progress = next((copy / "bandit" / "runs" / S2_MODULAR).glob("*/seed=*/progress.csv"))
    lines = progress.read_text().splitlines()
    # A restored trial re-logs its last iteration; the second log must win.
    relog = lines[-1].replace("0.703125,", "0.5,", 1)
    progress.write_text("\n".join([*lines, relog]) + "\n")
    tr = loaders.load_training(copy)
    s2 = tr[tr["experiment"] == S2_MODULAR]
    assert len(s2) == 8
    assert s2.loc[s2["training_iteration"] == 8, "return_mean"].item() == 0.5


def test_evals() -> None:
    ev = loaders.load_evals(FIXTURE)
    assert len(ev) == 16  # 4 trials x 4 training partners
    row = ev[(ev["experiment"] == S2_MODULAR) & (ev["partner"] == "hand-train-0")].iloc[0]
    assert row["mean_return"] == 0.79 and row["exact_return"] == pytest.approx(0.8608376383781433)
    assert row["marginal_distance"] == pytest.approx(0.7836605310440063)
    assert ev.loc[ev["label"] == "no_task_logits", "marginal_distance"].isna().all()  # BaselineModular has none


def test_adaptation_points() -> None:
    ad = loaders.load_adaptation(FIXTURE)
    assert len(ad) == 15  # 3 files x 1 partner x 5 evaluation points
    assert set(ad["population"]) == {"bandit-s2-hand"}
    assert sorted(ad["label"].unique()) == ["agg", "modular-lam0.5", "scratch"]
    assert sorted(ad["steps"].unique()) == [0, 16, 32, 48, 64]
    scratch = ad[ad["label"] == "scratch"]
    assert set(scratch["experiment"]) == {S2_MODULAR}  # scratch shares the modular run's seed
    assert (ad["trial"] == "point_0/seed=0").all()  # <grid point>/seed=<s>: the replica folder, named within its experiment


def test_zeroshot_and_marginals() -> None:
    zs = loaders.load_zeroshot(FIXTURE)
    assert len(zs) == 8 and set(zs["population"]) == {"bandit-s1-hand"}
    assert sorted(zs["label"].unique()) == ["modular-lam0.5", "no_task_logits"]
    mg = loaders.load_marginals(FIXTURE)
    assert len(mg) == 3
    d = mg.set_index(["population", "label"])["distance"]
    assert d[("bandit-s2-hand", "agg")] == pytest.approx(0.36647313833236694)
    assert d[("bandit-s1-hand", "modular-lam0.5")] == pytest.approx(0.9344931840896606)


def test_selfplay_and_crossplay() -> None:
    sp = loaders.load_selfplay_reports(FIXTURE)
    assert len(sp) == 20 and sp["passed"].dtype == bool and sp["passed"].all()
    assert sp.groupby("split").size().to_dict() == {"test": 10, "train": 10}
    matrices = loaders.load_crossplay(FIXTURE)
    assert list(matrices) == ["bandit-s2-hand__bandit-s2-hand"]
    m = matrices["bandit-s2-hand__bandit-s2-hand"]
    assert m.shape == (8, 8) and (np.diag(m.to_numpy()) == 1.0).all()


def test_empty_root_gives_empty_frames_with_columns(tmp_path: Path) -> None:
    assert loaders.load_training(tmp_path).empty
    assert list(loaders.load_adaptation(tmp_path).columns) == loaders.ADAPT_COLUMNS
    assert list(loaders.load_zeroshot(tmp_path).columns) == loaders.ZEROSHOT_COLUMNS
    assert loaders.load_marginals(tmp_path).empty and loaders.load_evals(tmp_path).empty
    assert loaders.load_selfplay_reports(tmp_path).empty and loaders.load_crossplay(tmp_path) == {}
    assert loaders.load_stage_times(tmp_path).empty


def test_user_study_csvs_concatenate(tmp_path: Path) -> None:
    header = "pair,task,context,try,action_1,action_2\n"
    (tmp_path / "s1.csv").write_text(header + "1,train,A,1,1,1\n1,train,B,1,3,4\n")
    (tmp_path / "s2.csv").write_text(header + "1,train,A,1,2,1\n")  # pair 1 again: a different session
    df = loaders.load_user_study_csvs(tmp_path)
    assert len(df) == 3
    assert sorted(df["pair_id"].unique()) == ["s1.csv:1", "s2.csv:1"]
    assert df["coordinated"].tolist() == [1, 0, 0]
    both = loaders.load_user_study_csvs([tmp_path / "s1.csv", tmp_path / "s2.csv"])
    assert len(both) == 3
    paper_table = loaders.load_user_study_csvs()
    assert len(paper_table) == 276 and set(paper_table["source"]) == {"user_study.csv"}
    (tmp_path / "bad.csv").write_text(header + "1,train,D,1,1,1\n")
    with pytest.raises(ValueError, match="context"):
        loaders.load_user_study_csvs(tmp_path)
    with pytest.raises(FileNotFoundError):
        loaders.load_user_study_csvs(tmp_path / "absent.csv")


def test_load_sweep_reads_an_experiment_folder(tmp_path) -> None:
    runs = FIXTURE / "bandit" / "runs"
    sweep = tmp_path / "my-sweep"
    for i, trial in enumerate(sorted(runs.glob("bandit-s2-hand__*/point_*"))):
        shutil.copytree(trial, sweep / f"EgoTrainable_{i}")
    curves = loaders.load_sweep(sweep)
    assert set(curves["population"]) == {"bandit-s2-hand"}  # from config.yaml, not the folder name
    assert sorted(set(curves["method"])) == ["agg", "modular"]
    assert curves.groupby("trial")["training_iteration"].apply(lambda s: s.is_monotonic_increasing and s.is_unique).all()
    with pytest.raises(ValueError, match="holds no trained-ego trial"):
        loaders.load_sweep(tmp_path / "empty")
