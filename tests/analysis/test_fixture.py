"""The analysis fixture is a reproduction in the current run-folder layout, and `fixture_builder` is how it is made.

The fixture (`fixtures/repro/bandit`) holds the numbers of a real quick bandit reproduction
(`reproduce bandit --quick`, one seed, recorded 2026-11-23), laid out as reproductions are
now: egos in `runs/<experiment>/point_0/seed=0/` with a sealed config, the replica's own
progress.csv (that run logged no `head_l2`: its column is empty), plan.json with its stages,
items and report facts, markers listing what they cover. The tests of `analysis` assert its
numbers, so it is laid out anew rather than re-run. `fixture_builder.slim` keeps of a
reproduction what the analysis reads. Also here: the one test of the older trial-as-ego
layout, which the loaders still read.
"""

from __future__ import annotations

import csv
import io
import json
import shutil
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest

from analysis import loaders
from rllib_conv.common.run_folders import CONFIG_FILE, EVAL_FILE, PLAN_FILE, REPLICA_PREFIX, marker_path, read_marker
from rllib_conv.common.sealed import digest_path, verify_file
from tests.analysis.fixture_builder import main, slim

FIXTURE = Path(__file__).parent / "fixtures" / "repro"
GAME = FIXTURE / "bandit"
EXPERIMENTS = [
    "bandit-s1-hand__modular-lam0.5",
    "bandit-s1-hand__no_task_logits",
    "bandit-s2-hand__agg",
    "bandit-s2-hand__modular-lam0.5",
]
# The tables with a `run` column (a trained ego's folder, on every row).
TABLES = [
    "marginals.csv",
    *(p.relative_to(GAME).as_posix() for folder in ("adaptation", "zeroshot") for p in sorted((GAME / folder).glob("*.csv"))),
]


def files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_every_trained_ego_is_a_replica_folder_of_a_grid_point() -> None:
    egos = loaders.trial_dirs(GAME)
    assert [e.relative_to(GAME / "runs").as_posix() for e in egos] == [f"{x}/point_0/seed=0" for x in EXPERIMENTS]
    for ego in egos:
        assert ego.name.startswith(REPLICA_PREFIX) and (ego.parent.parent / "experiment.yaml").is_file()
        assert {p.name for p in ego.iterdir()} == {CONFIG_FILE, digest_path(CONFIG_FILE).name, "progress.csv", EVAL_FILE}
        verify_file(ego / CONFIG_FILE)  # sealed as the trainer seals it, and unchanged


def test_every_run_in_the_tables_names_a_trained_ego_of_the_fixture() -> None:
    egos = set(loaders.trial_dirs(GAME))
    assert len(TABLES) == 6
    for table in TABLES:
        runs = set(pd.read_csv(GAME / table)["run"])
        assert runs and all(not Path(r).is_absolute() and GAME / r in egos for r in runs), table


def test_the_plan_lists_its_stages_and_every_marker_covers_its_items() -> None:
    plan = json.loads((GAME / PLAN_FILE).read_text())
    # Every stage but the held-out evaluation, which the bandit's plan does not declare.
    assert (
        plan["stages"] == [s for s in loaders.STAGES if s not in ("heldout", "evaluate")] and plan["report"]["max_score"] == 1.0
    )
    for stage in plan["stages"]:
        assert read_marker(marker_path(GAME, stage))[1] == plan["items"][stage]


def test_the_fixture_is_what_the_builder_keeps(tmp_path: Path) -> None:
    written = slim(GAME, tmp_path / "bandit")
    assert len(written) == len(files(GAME))
    assert files(tmp_path / "bandit") == files(GAME)


def with_runs(table: Path, change: Callable[[str], str]) -> None:
    """Rewrite the `run` column of CSV `table` (through the csv module: every other cell keeps its text)."""
    rows = list(csv.reader(io.StringIO(table.read_text())))
    column = rows[0].index("run")
    for row in rows[1:]:
        row[column] = change(row[column])
    out = io.StringIO()
    csv.writer(out, lineterminator="\n").writerows(rows)
    table.write_text(out.getvalue())


def full_reproduction(tmp_path: Path) -> Path:
    """The fixture as a run leaves it: absolute run paths, checkpoints, a stage's Tune run with its trials' files."""
    game = tmp_path / "out" / "bandit"
    shutil.copytree(GAME, game)
    for table in TABLES:
        with_runs(game / table, lambda run: str(game / run))
    for ego in loaders.trial_dirs(game):
        (ego / "checkpoint_000000" / "learner_group").mkdir(parents=True)
        (ego / "checkpoint_000000" / "learner_group" / "state.pkl").write_bytes(b"weights")
    stage = game / "runs" / "train-stage-0e9e6cc6d10b"
    (stage / "EgoTrainable_f1e41_00000_0").mkdir(parents=True)
    (stage / "experiment.yaml").write_text("experiments: [bandit-s2-hand__agg]\n")
    for name in ("progress.csv", "result.json", "params.json", "events.out.tfevents.1.vm"):
        (stage / "EgoTrainable_f1e41_00000_0" / name).write_text("{}\n")
    return game


def test_the_builder_keeps_what_the_analysis_reads_with_runs_relative(tmp_path: Path) -> None:
    game = full_reproduction(tmp_path)
    slim(game, tmp_path / "fixture")
    kept = files(tmp_path / "fixture")
    assert kept.pop("runs/train-stage-0e9e6cc6d10b/experiment.yaml") == b"experiments: [bandit-s2-hand__agg]\n"
    assert kept == files(GAME)  # no checkpoint, no Tune trial file; the run paths relative again


def test_the_builder_refuses_the_older_layout_and_runs_elsewhere_writing_nothing(tmp_path: Path, capsys) -> None:
    game = tmp_path / "bandit"
    shutil.copytree(GAME, game)
    shutil.move(
        game / "runs" / "bandit-s2-hand__agg" / "point_0" / "seed=0", game / "runs" / "bandit-s2-hand__agg" / "EgoTrainable_0"
    )
    with pytest.raises(SystemExit) as exit_:
        main([str(game), str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count("\n") == 1 and "EgoTrainable_0" in err and "trial-as-ego" in err
    assert not (tmp_path / "out").exists()

    game = full_reproduction(tmp_path / "elsewhere")
    with_runs(game / "marginals.csv", lambda run: "/somewhere/else/seed=0")
    with pytest.raises(ValueError, match="marginals.csv: run '/somewhere/else/seed=0' lies outside the game folder"):
        slim(game, tmp_path / "out")
    assert not (tmp_path / "out").exists()
    with pytest.raises(ValueError, match="exists"):
        slim(GAME, tmp_path)


def test_an_older_trial_as_ego_folder_still_loads_from_its_result_json(tmp_path: Path) -> None:
    # Before replicas, a Tune trial folder was the ego itself, and Tune's result.json (one JSON object a line,
    # the trial's config repeated on each) stood in for a missing progress.csv.
    ego = GAME / "runs" / "bandit-s2-hand__modular-lam0.5" / "point_0" / "seed=0"
    trial = tmp_path / "bandit" / "runs" / "bandit-s2-hand__modular-lam0.5" / "EgoTrainable_4f500_00000_0"
    trial.mkdir(parents=True)
    for name in (CONFIG_FILE, EVAL_FILE):
        shutil.copyfile(ego / name, trial / name)
    rows = pd.read_csv(ego / "progress.csv").to_dict("records")
    (trial / "result.json").write_text("".join(json.dumps({**row, "config": {"seed": 0}}) + "\n" for row in rows))
    (tmp_path / "bandit" / PLAN_FILE).write_text(json.dumps({"game": "bandit"}))

    current = loaders.load_training(GAME).query("experiment == 'bandit-s2-hand__modular-lam0.5'")
    older = loaders.load_training(tmp_path)
    assert older["trial"].unique().tolist() == ["EgoTrainable_4f500_00000_0"]
    assert older["experiment"].unique().tolist() == ["bandit-s2-hand__modular-lam0.5"]
    assert older["return_mean"].tolist() == current["return_mean"].tolist() and len(older) == 8
    assert (
        loaders.load_evals(tmp_path)["mean_return"].tolist()
        == loaders.load_evals(GAME).query("experiment == 'bandit-s2-hand__modular-lam0.5'")["mean_return"].tolist()
    )
