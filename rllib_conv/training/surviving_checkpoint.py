"""Resume a trial whose checkpoint named by Tune's experiment state was pruned before the state was saved again.

Tune prunes a trial's old checkpoints (`keep_checkpoints`) as soon as it registers a new
one, but writes its experiment state (which names each trial's latest checkpoint) only
every few seconds. A run killed in between leaves a state that names a checkpoint no
longer on disk, and Tune fails that trial on resume ("does not exist on storage
anymore"). Pruning keeps the newest checkpoints, so a later one survives:
`ResumeFromSurvivingCheckpoint` resumes the trial from the oldest surviving successor
(its iteration counts from `TRIAL_METRICS_FILE`, which every checkpoint holds), or from
the start if none survives. `AlgorithmTrainable.restore` numbers the checkpoints that
follow from the one restored (`checkpoint_index`), so none is written under another's name.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from ray.train._internal.checkpoint_manager import _TrainingResult
from ray.tune import Callback, Checkpoint
from ray.tune.result import EPISODES_TOTAL, TIME_TOTAL_S, TIMESTEPS_TOTAL, TRAINING_ITERATION

from rllib_conv.common.run_folders import checkpoints
from rllib_conv.common.sealed import verify

TRIAL_METRICS_FILE = "trial_metrics.json"  # in a trial checkpoint: Tune's counters when it was saved
RESTORED_METRICS = (TRAINING_ITERATION, TIME_TOTAL_S, TIMESTEPS_TOTAL, EPISODES_TOTAL)  # what `Trainable.restore` reads


def trial_metrics(trainable: Any) -> dict[str, Any]:
    """The Tune counters of `trainable` (a `tune.Trainable`) that a restore from a checkpoint saved now sets again."""
    values = (trainable.iteration, trainable._time_total, trainable._timesteps_total, trainable._episodes_total)
    return dict(zip(RESTORED_METRICS, values))


def checkpoint_index(checkpoint: str | Path) -> int:
    """The number in a checkpoint folder's name (`checkpoint_000007` -> 7)."""
    return int(Path(checkpoint).name.rsplit("_", 1)[1])


def surviving_successor(named: str | Path) -> Path | None:
    """The oldest complete checkpoint of `named`'s trial that is newer than `named` and records its metrics, or None."""
    for candidate in checkpoints(Path(named).parent):
        if checkpoint_index(candidate) <= checkpoint_index(named) or not (candidate / TRIAL_METRICS_FILE).is_file():
            continue
        try:
            verify(candidate)
        except ValueError:
            continue  # interrupted while being written
        return candidate
    return None


class ResumeFromSurvivingCheckpoint(Callback):
    """When a trial starts from a checkpoint that is gone, point it at its surviving successor (or at no checkpoint).

    Runs on the driver before Tune asks the trial's worker to restore (`on_trial_start`), on
    local or mounted storage. Checkpoints that are gone leave Tune's bookkeeping too, so
    that its pruning does not fail on them later.
    """

    def on_trial_start(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        named = trial.latest_checkpoint_result
        if named is None or Path(named.checkpoint.path).exists():
            return
        manager = trial.run_metadata.checkpoint_manager
        # Tune's checkpoint manager has no public way to forget checkpoints; these two fields are its whole record.
        manager._checkpoint_results = [r for r in manager._checkpoint_results if Path(r.checkpoint.path).exists()]
        successor = surviving_successor(named.checkpoint.path)
        if successor is None:
            manager._latest_checkpoint_result = None
            note = "no later one survives: it starts over"
        else:
            metrics = json.loads((successor / TRIAL_METRICS_FILE).read_text())
            result = _TrainingResult(checkpoint=Checkpoint.from_directory(str(successor)), metrics=metrics)
            manager._checkpoint_results.append(result)
            manager._latest_checkpoint_result = result
            trial.storage.current_checkpoint_index = checkpoint_index(successor)
            note = f"it resumes from {successor}"
        trial.invalidate_json_state()
        trial.run_metadata.invalidate_cache()
        print(f"note: trial {trial}: its checkpoint {named.checkpoint.path} is gone; {note}", file=sys.stderr, flush=True)
