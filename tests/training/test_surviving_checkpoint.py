"""A trial whose named checkpoint is gone resumes from the oldest complete successor, or starts over without one.

The end-to-end case (a killed sweep resumed with its named checkpoint pruned) is in
tests/sweeps/test_resume_after_kill.py; these check the choice and Tune's bookkeeping.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from types import SimpleNamespace

from ray.train._internal.checkpoint_manager import _CheckpointManager, _TrainingResult
from ray.tune import Checkpoint, CheckpointConfig

from rllib_conv.common.sealed import seal
from rllib_conv.training.surviving_checkpoint import (
    TRIAL_METRICS_FILE,
    ResumeFromSurvivingCheckpoint,
    checkpoint_index,
    surviving_successor,
)


def _checkpoint(trial: Path, index: int, *, metrics: bool = True, sealed: bool = True) -> Path:
    folder = trial / f"checkpoint_{index:06d}"
    folder.mkdir(parents=True)
    (folder / "state.bin").write_bytes(bytes([index]))
    if metrics:
        (folder / TRIAL_METRICS_FILE).write_text(json.dumps({"training_iteration": 3 * (index + 1)}))
    if sealed:
        seal(folder)
    return folder


def _trial(named: Path) -> SimpleNamespace:
    """A Tune trial as the callback sees it: its checkpoint manager remembers `named` (and an older one) as kept."""
    manager = _CheckpointManager(CheckpointConfig(num_to_keep=2))
    for path in (named.with_name("checkpoint_000000"), named):
        manager.register_checkpoint(_TrainingResult(checkpoint=Checkpoint.from_directory(str(path)), metrics={}))
    return SimpleNamespace(
        latest_checkpoint_result=manager.latest_checkpoint_result,
        run_metadata=SimpleNamespace(checkpoint_manager=manager, invalidate_cache=lambda: None),
        storage=SimpleNamespace(current_checkpoint_index=checkpoint_index(named)),
        invalidate_json_state=lambda: None,
    )


def test_the_oldest_complete_successor_with_metrics_is_chosen(tmp_path) -> None:
    named = tmp_path / "checkpoint_000003"
    _checkpoint(tmp_path, 2)  # older: never a successor
    _checkpoint(tmp_path, 4, sealed=False)  # interrupted while being written
    _checkpoint(tmp_path, 5, metrics=False)  # written before checkpoints recorded their counts
    _checkpoint(tmp_path, 6)
    _checkpoint(tmp_path, 7)
    assert surviving_successor(named) == tmp_path / "checkpoint_000006"
    shutil.rmtree(tmp_path / "checkpoint_000006")
    shutil.rmtree(tmp_path / "checkpoint_000007")
    assert surviving_successor(named) is None


def test_a_trial_resumes_from_the_successor_with_its_own_counts(tmp_path, capsys) -> None:
    named = tmp_path / "checkpoint_000003"
    successor = _checkpoint(tmp_path, 4)
    trial = _trial(named)
    ResumeFromSurvivingCheckpoint().on_trial_start(iteration=0, trials=[trial], trial=trial)
    manager = trial.run_metadata.checkpoint_manager
    assert Path(manager.latest_checkpoint_result.checkpoint.path) == successor
    assert manager.latest_checkpoint_result.metrics == {"training_iteration": 15}
    assert [Path(r.checkpoint.path) for r in manager._checkpoint_results] == [successor]  # the gone ones are forgotten
    assert trial.storage.current_checkpoint_index == 4
    assert f"it resumes from {successor}" in capsys.readouterr().err


def test_a_trial_without_a_successor_starts_over(tmp_path, capsys) -> None:
    _checkpoint(tmp_path, 4, metrics=False)
    trial = _trial(tmp_path / "checkpoint_000003")
    ResumeFromSurvivingCheckpoint().on_trial_start(iteration=0, trials=[trial], trial=trial)
    manager = trial.run_metadata.checkpoint_manager
    assert manager.latest_checkpoint_result is None and manager._checkpoint_results == []
    assert "it starts over" in capsys.readouterr().err


def test_a_trial_whose_checkpoint_exists_is_left_alone(tmp_path) -> None:
    named = _checkpoint(tmp_path, 3)
    _checkpoint(tmp_path, 4)
    trial = _trial(named)
    before = trial.latest_checkpoint_result
    ResumeFromSurvivingCheckpoint().on_trial_start(iteration=0, trials=[trial], trial=trial)
    assert trial.run_metadata.checkpoint_manager.latest_checkpoint_result is before
    assert trial.storage.current_checkpoint_index == 3
