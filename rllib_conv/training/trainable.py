"""`AlgorithmTrainable`: the one Tune Trainable base class of every pipeline (train, adapt, zero-shot, self-play).

It holds an RLlib algorithm in `self.algo`, runs torch on one thread, saves the algorithm
and the RNG state (`rng_state`) into sealed checkpoints and verifies them before
restoring, stops the algorithm when the trial ends, and asks Ray for what the trial's
`run` settings say (`tuning.trial_resources`) and reports where its time goes (`timings`).
Subclasses build `self.algo` in `build` (given the trial's own config: its job in a stage
run), implement `advance` (one Tune step), say in `outputs_complete` when the results a
trial writes are already there (it then runs nothing: a trial killed between writing them
and Tune recording it as finished is not run twice), and write state beyond the
algorithm's in `save_extra` / read it in `load_extra`. A worker runs one trial after another
(`reset_config`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import ray
import torch
from ray import tune
from ray.tune.execution.placement_groups import PlacementGroupFactory

from rllib_conv.common.run_folders import CHECKPOINT_PREFIX
from rllib_conv.common.sealed import seal, verify
from rllib_conv.training import rng_state
from rllib_conv.training.surviving_checkpoint import TRIAL_METRICS_FILE, checkpoint_index, trial_metrics
from rllib_conv.training.timings import Timings
from rllib_conv.training.tuning import trial_job, trial_resources

TIMINGS_FILE = "timings.json"  # in a trial checkpoint: the trial's `Timings` so far


class AlgorithmTrainable(tune.Trainable):
    """A Tune trial driving one RLlib algorithm (`self.algo`); see the module docstring."""

    algo: Any

    def setup(self, config: dict[str, Any]) -> None:
        # The learner slows down 10-40x when torch threads compete with env runners.
        torch.set_num_threads(1)
        self.timings = Timings()
        self.algo = None
        job = trial_job(config)
        # A trial that wrote its results and was killed before Tune recorded it as finished
        # (Tune saves its experiment state every few seconds) ends at once when run again.
        self.finished_before = self.outputs_complete(job)
        if not self.finished_before:
            with self.timings.measure("setup"):
                self.build(job)

    @property
    def trial_folder(self) -> Path:
        """The trial's folder in the experiment's storage (`<storage>/<experiment>/<trial>/`), where its results go.

        Not `logdir`: that is the trial's working directory, copied to storage only from time
        to time, and new (empty) when the trial runs again after a kill.
        """
        storage = getattr(self, "_storage", None)
        folder = Path(storage.trial_fs_path) if storage is not None and storage.trial_fs_path else Path(self.logdir)
        folder.mkdir(parents=True, exist_ok=True)
        return folder

    def outputs_complete(self, config: dict[str, Any]) -> bool:
        """Whether this trial's results are already on disk, complete (then it runs nothing)."""
        return False

    def build(self, config: dict[str, Any]) -> None:
        """Build `self.algo` (and whatever else the trial needs) from the trial's config."""
        raise NotImplementedError

    def advance(self) -> dict[str, Any]:
        """One Tune step: train and/or evaluate; return the result (with `done: True` at the end)."""
        raise NotImplementedError

    def step(self) -> dict[str, Any]:
        if self.finished_before:
            return {"done": True, "finished_before": True}
        result = self.advance()
        # Which Ray node ran the trial: how a stage spread over a cluster (`benchmarks/stage_concurrency.py`).
        return {**result, **self.timings.metrics(), "node_id": ray.get_runtime_context().get_node_id()}

    def save_extra(self, checkpoint_dir: Path) -> None:
        """Write state beyond the algorithm's into the checkpoint (before it is sealed)."""

    def load_extra(self, checkpoint_dir: Path) -> None:
        """Read what `save_extra` wrote."""

    def save_checkpoint(self, checkpoint_dir: str) -> None:
        if self.algo is None:  # finished before: nothing to resume from
            seal(checkpoint_dir)
            return
        self.algo.save_to_path(checkpoint_dir)
        (Path(checkpoint_dir) / TRIAL_METRICS_FILE).write_text(json.dumps(trial_metrics(self)))
        rng_state.save(self.algo, checkpoint_dir)
        (Path(checkpoint_dir) / TIMINGS_FILE).write_text(json.dumps(self.timings.state()))
        self.save_extra(Path(checkpoint_dir))
        seal(checkpoint_dir)

    def restore(self, checkpoint_path: Any) -> None:
        super().restore(checkpoint_path)
        # The next checkpoint follows the one restored, whichever Tune's experiment state named (`surviving_checkpoint`).
        checkpoint = getattr(checkpoint_path, "checkpoint", checkpoint_path)
        path = Path(getattr(checkpoint, "path", checkpoint))
        if self._storage is not None and path.name.startswith(CHECKPOINT_PREFIX):
            self._storage.current_checkpoint_index = checkpoint_index(path)

    def load_checkpoint(self, checkpoint: str) -> None:
        verify(checkpoint)
        if self.algo is None:
            return
        self.algo.restore_from_path(checkpoint)
        rng_state.load(self.algo, checkpoint)
        timings = Path(checkpoint) / TIMINGS_FILE
        if timings.is_file():
            self.timings.load(json.loads(timings.read_text()))
        self.load_extra(Path(checkpoint))

    def cleanup(self) -> None:
        if self.algo is not None:
            self.algo.stop()

    def reset_config(self, new_config: dict[str, Any]) -> bool:
        """Take the next trial in this worker (Tune's `reuse_actors`): stop this trial's algorithm, set up the new one's.

        A new Tune worker costs ~4 s of process start and imports, more than a bandit
        self-play pair or adaptation pack trains. Nothing carries over: `build` sets every
        attribute a trial uses, and building an algorithm seeds the global generators.
        """
        self.cleanup()
        self.setup(new_config)
        return True

    @classmethod
    def default_resource_request(cls, config: dict[str, Any]) -> PlacementGroupFactory:
        config = trial_job(config)
        return trial_resources(config.get("run") if isinstance(config.get("run"), dict) else None)
