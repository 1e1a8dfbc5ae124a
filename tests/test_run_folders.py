"""Stage names and markers (`rllib_conv.common.run_folders`): known answers, and a marker is never half-written."""

from __future__ import annotations

from pathlib import Path

import pytest

from rllib_conv.common.run_folders import (
    STAGE_PREFIXES,
    STAGES,
    config_run_name,
    expected_stages,
    marker_path,
    read_marker,
    spec_digest,
    stage_run_name,
    stage_run_prefix,
    write_marker,
)

TWO_ADAPTS = {"experiments": ["a", "b"], "configs": [{"name": "a"}, {"name": "b"}]}
ONE_TRAIN = {"experiments": ["x"], "jobs": [{"seed": 0, "replica_seeds": [0], "export_to": "/r/x/point_0"}]}


def test_stage_runs_keep_the_names_they_had_so_earlier_runs_resume() -> None:
    # Digests computed with the code before the names moved here (sha1 of the sorted-key JSON):
    # a reproduction started then finds its Tune runs again.
    assert stage_run_name("adapt", ["a", "b"], TWO_ADAPTS) == "adapt-stage-0fd81fa732c5"
    assert stage_run_name("train", ["x"], ONE_TRAIN) == "train-stage-2db77aea34a9"
    assert (
        spec_digest({"configs": TWO_ADAPTS["configs"], "experiments": ["a", "b"]}) == "0fd81fa732c5"
    )  # key order does not count


def test_one_config_runs_under_its_own_name_except_in_the_train_stage() -> None:
    assert stage_run_name("adapt", ["pop__modular"], {"name": "pop__modular"}) == "adapt-pop__modular"
    assert stage_run_name("zeroshot", ["z"], {}) == config_run_name("zeroshot", "z") == "zeroshot-z"
    assert stage_run_name("selfplay", ["blocks-selfplay"], {"name": "blocks-selfplay"}) == "selfplay-blocks-selfplay"
    assert stage_run_name("train", ["x"], ONE_TRAIN).startswith(stage_run_prefix("train"))  # `x/` holds the egos
    assert [stage_run_prefix(s) for s in ("train", "adapt", "zeroshot")] == ["train-stage-", "adapt-stage-", "zeroshot-stage-"]


def test_every_stage_run_is_told_from_an_experiment_by_its_prefix() -> None:
    runs = [stage_run_name(s, ["a", "b"], TWO_ADAPTS) for s in ("train", "adapt", "zeroshot")]
    runs += [stage_run_name(s, ["pop__m"], {}) for s in ("adapt", "zeroshot", "selfplay")]
    assert all(r.startswith(STAGE_PREFIXES) for r in runs)
    assert not "pop__modular-lam0.5".startswith(STAGE_PREFIXES)
    assert STAGES == ("selfplay", "train", "adapt", "zeroshot", "marginals", "heldout", "evaluate")
    assert expected_stages("bandit") == STAGES[:5]  # older folders: the held-out and evaluate stages came later


def test_a_marker_names_its_stage_and_holds_its_time_then_its_items(tmp_path: Path) -> None:
    marker = marker_path(tmp_path, "adapt")
    assert marker == tmp_path / "adapt.done"
    write_marker(marker, 61.04, ["pop__agg seeds=0,1", "pop__modular seeds=0,1"])
    assert marker.read_text() == "61.0 s\npop__agg seeds=0,1\npop__modular seeds=0,1\n"
    assert read_marker(marker) == (61.0, ["pop__agg seeds=0,1", "pop__modular seeds=0,1"])
    assert [p.name for p in tmp_path.iterdir()] == ["adapt.done"]  # nothing left beside it


def test_a_marker_killed_mid_write_leaves_the_one_it_had(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    marker = marker_path(tmp_path, "train")
    write_marker(marker, 12.0, ["a seeds=0"])
    real_write = Path.write_text

    def half_then_die(self: Path, text: str, *args, **kwargs) -> int:
        real_write(self, text[: len(text) // 2], *args, **kwargs)
        raise KeyboardInterrupt  # the process stopped between the two halves

    monkeypatch.setattr(Path, "write_text", half_then_die)
    with pytest.raises(KeyboardInterrupt):
        write_marker(marker, 99.0, ["a seeds=0", "b seeds=0", "c seeds=0"])
    monkeypatch.undo()
    assert read_marker(marker) == (12.0, ["a seeds=0"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["train.done"]  # and no torn temporary file
