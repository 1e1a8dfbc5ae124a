"""A trial's result files across a kill: copies kept at each checkpoint, put back before a resume, torn rows skipped."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from rllib_conv.training.callbacks import KeepLogsAtCheckpoints, TrimRerunResults, restore_checkpointed_logs

HEADER = "note,loss,training_iteration\n"


def _csv(iterations: range) -> str:
    # A quoted comma before the iteration column (as Tune writes a list value): a CSV reader still finds it.
    return HEADER + "".join(f'"[1, 2]",0.{i},{i}\n' for i in iterations)


def _json(iterations: range) -> str:
    return "".join(f'{{"loss": 0.{i}, "training_iteration": {i}}}\n' for i in iterations)


def _trial(staging: Path, storage: Path) -> SimpleNamespace:
    return SimpleNamespace(trial_id="t0", local_path=str(staging), path=str(storage))


def test_a_checkpoint_copies_the_staged_result_files_into_storage_and_a_resume_puts_them_back(tmp_path: Path) -> None:
    staging, storage = tmp_path / "staging" / "trial", tmp_path / "sweep" / "trial"
    staging.mkdir(parents=True)
    storage.mkdir(parents=True)
    (staging / "progress.csv").write_text(_csv(range(1, 22)))
    (staging / "result.json").write_text(_json(range(1, 22)))
    KeepLogsAtCheckpoints().on_checkpoint(iteration=0, trials=[], trial=_trial(staging, storage), checkpoint=None)
    assert (storage / "progress.csv.checkpointed").read_text() == _csv(range(1, 22))
    assert (storage / "result.json.checkpointed").read_text() == _json(range(1, 22))

    # Killed while Tune copied its staging folder over: storage's files torn (one cut mid-row, one empty).
    (storage / "progress.csv").write_text(_csv(range(1, 25))[:40])
    (storage / "result.json").write_text("")
    other = tmp_path / "sweep" / "no-checkpoint-yet"
    other.mkdir()
    (other / "progress.csv").write_text(_csv(range(1, 3)))
    restore_checkpointed_logs(tmp_path / "sweep")
    assert (storage / "progress.csv").read_text() == _csv(range(1, 22))
    assert (storage / "result.json").read_text() == _json(range(1, 22))
    assert (storage / "progress.csv.checkpointed").is_file()  # kept for a second kill before the next checkpoint
    assert (other / "progress.csv").read_text() == _csv(range(1, 3))  # nothing to put back: untouched
    assert not list((tmp_path / "sweep").glob("*/*.tmp"))


def test_no_copy_where_tune_writes_in_storage_itself(tmp_path: Path) -> None:
    (tmp_path / "progress.csv").write_text(_csv(range(1, 4)))
    KeepLogsAtCheckpoints().on_checkpoint(iteration=0, trials=[], trial=_trial(tmp_path, tmp_path), checkpoint=None)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["progress.csv"]


def test_rows_cut_short_by_a_kill_are_dropped_with_the_rerun_ones(tmp_path: Path) -> None:
    progress, results = tmp_path / "progress.csv", tmp_path / "result.json"
    progress.write_text(_csv(range(1, 6)) + '"[1, 2]",0.6')  # row 6 cut mid-row, before its iteration
    results.write_text(_json(range(1, 6)) + '{"loss": 0.6, "trai')
    trim = TrimRerunResults()
    assert trim._logged(progress) == trim._logged(results) == [1, 2, 3, 4, 5]
    # The trial resumed from its checkpoint at 3 reports iteration 4: rows 4, 5 and the torn one go.
    trim.on_trial_result(iteration=0, trials=[], trial=_trial(tmp_path, tmp_path), result={"training_iteration": 4})
    assert progress.read_text() == _csv(range(1, 4))
    assert results.read_text() == _json(range(1, 4))
