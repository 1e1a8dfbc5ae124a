"""The one stage runner (`rllib_conv.training.stage`): validate, pack, spread, name, fit, write tables.

`fit` and the cluster's CPU count are stood in for, so these check the skeleton's own
decisions (which trials, under which name, with which progress, which CSVs) without Ray;
the pipeline tests train through it for real.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pandas as pd
import pytest
from ray import tune

from rllib_conv.training import stage as stage_module
from rllib_conv.training.callbacks import StageProgress
from rllib_conv.training.stage import Stage, Table, configs_spec, packed_jobs, run_jobs, run_packed, validated, write_tables
from rllib_conv.training.tuning import JOB_KEY

TABLE = Table("rows.csv", ["run", "partner", "value"], order=["run", "partner"], what="test")
NO_CHECKPOINTS = tune.CheckpointConfig(checkpoint_at_end=False)


class _Trainable(tune.Trainable):
    """Never run: `fit` is stood in for."""


def _cfg(name: str, max_pack: int = 8) -> SimpleNamespace:
    return SimpleNamespace(name=name, max_pack=max_pack)


def _stage(**kwargs: Any) -> Stage:
    return Stage("adapt", _Trainable, NO_CHECKPOINTS, **{"units": "runs", "table": TABLE, **kwargs})


def test_configs_are_checked_in_order_and_their_names_must_differ() -> None:
    assert [c.name for c in validated([{"n": "a"}, {"n": "b"}], lambda raw: _cfg(raw["n"]), "adapt")] == ["a", "b"]
    with pytest.raises(ValueError, match=r"zero-shot configs must have different names; got \['a', 'b', 'a'\]"):
        validated([{"n": "a"}, {"n": "b"}, {"n": "a"}], lambda raw: _cfg(raw["n"]), "zero-shot")
    with pytest.raises(ValueError, match="stage: expected one of"):
        Stage("sweep", _Trainable, NO_CHECKPOINTS)


def test_a_stage_prints_one_line_with_a_label_and_one_per_result_without() -> None:
    assert _stage().progress(None) == "lines" and _stage().progress("") == "lines"
    progress = _stage().progress("[bandit] adapt")
    assert isinstance(progress, StageProgress) and progress.label == "[bandit] adapt"
    assert progress.units({JOB_KEY: {"runs": ["r0", "r1", "r2"]}}) == 3  # a waiting trial counts by its units
    selfplay = Stage("selfplay", _Trainable, NO_CHECKPOINTS, stops_early="a pair stops when it passes the gate").progress("sp")
    assert selfplay.units is None and selfplay.stops_early == "a pair stops when it passes the gate"


def test_units_pack_by_key_within_each_config_and_are_told_apart_by_its_index() -> None:
    raws = [{"name": "a", "population": "bandit-s2-hand"}, {"name": "b"}]
    cfgs = [_cfg("a", max_pack=2), _cfg("b")]
    units = [["a0", "a1", "a2", "x3"], ["b0"]]
    # 5 units on 1 core: packs of up to min(max_pack, 5) units; "x" units never share a trial with "a" ones.
    jobs = packed_jobs(_stage(), raws, cfgs, units, lambda i, unit: (i, unit[0]), cpus=1)
    assert jobs == [
        {"index": 0, "config": raws[0], "runs": ["a0", "a2"]},
        {"index": 0, "config": raws[0], "runs": ["a1"]},
        {"index": 0, "config": raws[0], "runs": ["x3"]},
        {"index": 1, "config": raws[1], "runs": ["b0"]},
    ]


def test_a_manifest_path_reaches_the_trials_absolute(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "pop.json").write_text("{}")
    monkeypatch.chdir(tmp_path)
    (job,) = packed_jobs(
        _stage(manifest_key="new_population"),
        [{"name": "z", "new_population": "pop.json"}],
        [_cfg("z")],
        [["r"]],
        lambda i, u: 0,
        cpus=1,
    )
    assert job["config"]["new_population"] == str(tmp_path / "pop.json")


def _stand_in_fit(
    monkeypatch: pytest.MonkeyPatch, cpus: int, tables: dict[int, list[dict[str, Any]] | None], root: Path
) -> list[dict[str, Any]]:
    """`fit` records its call and returns a result per trial whose folder holds the rows `tables[index]` (None: the trial failed)."""
    calls: list[dict[str, Any]] = []

    def fit(trainable, spec, param_space, name, storage, address, checkpoint, progress, loggers=()):
        calls.append(
            {
                "trainable": trainable,
                "spec": spec,
                "name": name,
                "checkpoint": checkpoint,
                "progress": progress,
                "loggers": loggers,
            }
        )
        jobs = param_space[JOB_KEY]["grid_search"]
        calls[-1]["jobs"] = jobs
        results = []
        for t, job in enumerate(jobs):
            folder = root / name / f"trial_{t}"
            folder.mkdir(parents=True)
            rows = tables[job["index"]]
            if rows is not None:
                pd.DataFrame([r for r in rows if r["run"] in job["runs"]]).to_csv(folder / TABLE.file, index=False)
            results.append(
                SimpleNamespace(config={JOB_KEY: job}, path=str(folder), error=None if rows is not None else RuntimeError("boom"))
            )
        return results

    monkeypatch.setattr(stage_module, "fit", fit)
    monkeypatch.setattr(stage_module, "cluster_cpus", lambda address=None: cpus)
    return calls


def test_one_config_runs_under_its_name_packed_and_spread_over_the_cores_and_writes_its_csv(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    rows = [{"run": f"r{k}", "partner": p, "value": 10 * k + i, "extra": 0} for k in (2, 0, 1) for i, p in enumerate("ba")]
    calls = _stand_in_fit(monkeypatch, cpus=2, tables={0: rows}, root=tmp_path / "runs")
    raw = {"name": "pop__m"}
    out = run_packed(
        _stage(),
        [raw],
        [_cfg("pop__m")],
        [["r0", "r1", "r2"]],
        lambda i, u: 0,
        tmp_path / "adaptation",
        tmp_path / "runs",
        label="[bandit] adapt",
    )
    (call,) = calls
    assert (
        call["name"] == "adapt-pop__m"
        and call["spec"] == raw
        and call["trainable"] is _Trainable
        and call["checkpoint"] is NO_CHECKPOINTS
    )
    assert [job["runs"] for job in call["jobs"]] == [["r0", "r2"], ["r1"]]  # 3 units on 2 cores: two trials
    assert isinstance(call["progress"], StageProgress)
    written = pd.read_csv(tmp_path / "adaptation" / "pop__m.csv")
    assert list(written.columns) == TABLE.columns  # only the table's columns, in its order
    assert list(zip(written["run"], written["partner"])) == [(f"r{k}", p) for k in range(3) for p in "ab"]
    pd.testing.assert_frame_equal(out["pop__m"], written)


def test_several_configs_run_as_one_stage_run_and_a_failed_pack_costs_only_its_configs_csv(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    good = [{"run": "g", "partner": "p", "value": 1.0}]
    calls = _stand_in_fit(monkeypatch, cpus=1, tables={0: good, 1: None}, root=tmp_path / "runs")
    raws = [{"name": "good"}, {"name": "bad"}]
    with pytest.raises(RuntimeError, match=r"1 test pack\(s\) failed, so \['bad'\] wrote no CSV"):
        run_packed(
            _stage(),
            raws,
            [_cfg("good"), _cfg("bad")],
            [["g"], ["b"]],
            lambda i, u: 0,
            tmp_path / "out",
            tmp_path / "runs",
            loggers=("wandb",),
        )
    (call,) = calls
    assert call["name"].startswith("adapt-stage-") and call["spec"] == configs_spec(raws, ["good", "bad"]) == {
        "experiments": ["good", "bad"],
        "configs": raws,
    }
    assert call["progress"] == "lines" and call["loggers"] == ("wandb",)
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["good.csv"]


def test_jobs_are_cut_with_their_first_unit_and_a_stage_without_units_key_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[tuple[Any, ...]] = []
    monkeypatch.setattr(stage_module, "fit", lambda *args, **kwargs: calls.append(args) or [])
    monkeypatch.setattr(stage_module, "cluster_cpus", lambda address=None: 2)
    train = Stage("train", _Trainable, NO_CHECKPOINTS, units="replica_seeds", first_key="seed")
    spec = {"experiments": ["x"], "jobs": ["every job"]}
    run_jobs(train, spec, [{"seed": 0, "replica_seeds": [0, 1, 2, 3]}], ["x"], tmp_path)
    (args,) = calls
    assert args[3] == train.run_name(["x"], spec) and args[3].startswith("train-stage-")
    assert args[2][JOB_KEY]["grid_search"] == [{"seed": 0, "replica_seeds": [0, 1]}, {"seed": 2, "replica_seeds": [2, 3]}]
    with pytest.raises(ValueError, match="Stage.units"):
        run_jobs(Stage("selfplay", _Trainable, NO_CHECKPOINTS), {}, [], ["p"], tmp_path)


def test_tables_of_a_config_are_gathered_in_order_whatever_order_its_packs_finished(tmp_path: Path) -> None:
    results = []
    for t, runs in enumerate([["r3", "r1"], ["r2"]]):
        folder = tmp_path / f"t{t}"
        folder.mkdir()
        pd.DataFrame({"value": [1.0] * len(runs), "partner": ["p"] * len(runs), "run": runs}).to_csv(
            folder / TABLE.file, index=False
        )
        results.append(SimpleNamespace(config={JOB_KEY: {"index": 0}}, path=str(folder), error=None))
    tables = write_tables(results, [_cfg("c")], TABLE, tmp_path / "out")
    assert list(tables["c"]["run"]) == ["r1", "r2", "r3"] and list(tables["c"].columns) == TABLE.columns
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["c.csv"]  # no temporary file left beside it
