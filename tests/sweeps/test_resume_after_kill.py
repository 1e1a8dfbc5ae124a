"""A sweep killed with SIGKILL mid-way resumes: every trial finishes, no iteration repeats or is
missing, and the results equal those of an uninterrupted run with the same seeds, also when the
checkpoint that Tune's experiment state names was pruned before the state was saved again."""

from __future__ import annotations

import json
import os
import pickle
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
import torch
import yaml
from ray.tune.experiment.trial import Trial

from rllib_conv.common.run_folders import RL_MODULE_DIR, checkpoints
from rllib_conv.training.callbacks import CHECKPOINTED
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.surviving_checkpoint import TRIAL_METRICS_FILE
from tests.sweeps.killing import kill_ray_instance, private_ray_tmp

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)

SWEEP = {
    "name": "sweep",
    "population": "bandit-s1-hand",
    "lam": {"grid_search": [0.0, 0.5]},
    "model": {"hidden": 8},
    "ppo": {"rollout_per_partner": 16, "num_epochs": 2},
    "run": {"timesteps": 2560, "checkpoint_every": 3, "keep_checkpoints": 2},
}
ITERATIONS = 2560 // 64


def _sweep(config: Path, storage: Path, ray_tmp: str, *extra: str) -> subprocess.Popen:
    env = {**os.environ, "RAY_TMPDIR": ray_tmp, "OMP_NUM_THREADS": "1", "RAY_ADDRESS": ""}
    cmd = [sys.executable, "-m", "rllib_conv.cli", "sweep", str(config), "--storage", str(storage), *extra]
    return subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)


def _iterations(storage: Path) -> list[int]:
    done = []
    for progress in storage.glob("sweep/*/progress.csv"):
        try:
            done.append(int(pd.read_csv(progress)["training_iteration"].max()))
        except (pd.errors.EmptyDataError, KeyError, ValueError):
            done.append(0)
    return done


def _named_checkpoints(storage: Path) -> dict[str, Path]:
    """Per trial folder name: the checkpoint that Tune's experiment state names as the trial's latest (read as Tune reads it)."""
    (state_file,) = storage.glob("sweep/experiment_state-*.json")
    named = {}
    for trial_state, run_metadata in json.loads(state_file.read_text())["trial_data"]:
        trial = Trial.from_json_state(trial_state, stub=True)
        trial.restore_run_metadata(run_metadata)
        if trial.checkpoint is not None:
            named[Path(trial.checkpoint.path).parent.name] = Path(trial.checkpoint.path)
    return named


def _prune_before_the_state_names_a_successor(storage: Path) -> Path:
    """Make one trial's named checkpoint gone with a complete later one on disk: what a kill between a prune and
    Tune's next save of its state leaves (seen once in CI). Returns the trial's folder."""
    named = _named_checkpoints(storage)
    assert named, "Tune should have saved a state naming a checkpoint before the kill"
    folder, checkpoint = sorted(named.items())[-1]
    if not checkpoint.exists():
        # The kill itself fell between a prune and Tune's next save of its state (seen once in CI): Tune
        # pruned it only after registering newer ones, so the case is already on disk.
        return storage / "sweep" / folder
    successor = checkpoint.with_name(f"checkpoint_{int(checkpoint.name.rsplit('_', 1)[1]) + 1:06d}")
    if not _registered(successor):
        # Tune prunes a checkpoint only after registering newer ones, and registering copies the logs
        # (`KeepLogsAtCheckpoints`): a later checkpoint the driver had not registered yet cannot be what
        # survives a prune. A copy of the named one plays the registered successor (same state, same counts).
        shutil.rmtree(successor, ignore_errors=True)
        shutil.copytree(checkpoint, successor)
    shutil.rmtree(checkpoint)
    return storage / "sweep" / folder


def _registered(checkpoint: Path) -> bool:
    """Whether the driver registered `checkpoint`: the trial's logs kept at its last registered checkpoint reach it."""
    logs = checkpoint.parent / f"progress.csv{CHECKPOINTED}"
    if not (checkpoint / TRIAL_METRICS_FILE).is_file() or not logs.is_file():
        return False
    iteration = json.loads((checkpoint / TRIAL_METRICS_FILE).read_text())["training_iteration"]
    return iteration <= pd.read_csv(logs)["training_iteration"].max()


def _outcome(storage: Path) -> dict[float, dict]:
    """Per lam: the final evaluation and task-module weights of its trained ego, its Tune trial folder."""
    out = {}
    for ego in sorted(p.parent for p in storage.glob("sweep/*/seed=*/config.yaml")):
        lam = yaml.safe_load((ego / "config.yaml").read_text())["lam"]
        weights = pickle.loads((last_checkpoint(ego) / RL_MODULE_DIR / "task" / "module_state.pkl").read_bytes())
        out[lam] = {"eval": json.loads((ego / "eval.json").read_text()), "weights": weights, "trial": ego.parent, "ego": ego}
    return out


def test_sigkill_then_resume_matches_an_uninterrupted_sweep(tmp_path) -> None:
    config = tmp_path / "sweep.yaml"
    config.write_text(yaml.safe_dump(SWEEP))

    reference, ray_a = tmp_path / "reference", private_ray_tmp()
    proc = _sweep(config, reference, ray_a)
    out, _ = proc.communicate(timeout=600)
    kill_ray_instance(ray_a)
    assert proc.returncode == 0, out.decode()[-3000:]

    interrupted, ray_b = tmp_path / "interrupted", private_ray_tmp()
    proc = _sweep(config, interrupted, ray_b)
    deadline = time.time() + 300
    while time.time() < deadline and not any(i >= ITERATIONS // 2 for i in _iterations(interrupted)):
        time.sleep(0.2)
    assert any(0 < i < ITERATIONS for i in _iterations(interrupted)), "the sweep should be killed mid-way"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    kill_ray_instance(ray_b)
    killed_at = _iterations(interrupted)
    # Tune copies its result files to storage in the background, file over file: a kill during that copy
    # leaves them torn (seen once under load, which lost a resumed trial's rows before its checkpoint).
    # Tear them all here, mid-row, so that every resume meets that case.
    for path in [*interrupted.glob("sweep/*/progress.csv"), *interrupted.glob("sweep/*/result.json")]:
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    pruned = _prune_before_the_state_names_a_successor(interrupted)

    ray_c = private_ray_tmp()
    proc = _sweep(config, interrupted, ray_c, "--resume")
    out, _ = proc.communicate(timeout=600)
    kill_ray_instance(ray_c)
    assert proc.returncode == 0, out.decode()[-3000:]
    assert "--- 2/2 trials finished ---" in out.decode()  # the live table's last print
    assert f"it resumes from {pruned}/checkpoint_" in out.decode()

    resumed, expected = _outcome(interrupted), _outcome(reference)
    assert sorted(resumed) == sorted(expected) == [0.0, 0.5]
    for lam in expected:
        assert len(checkpoints(resumed[lam]["trial"])) <= SWEEP["run"]["keep_checkpoints"]  # old ones pruned
        for folder in (resumed[lam]["trial"], resumed[lam]["ego"]):  # Tune's log and the ego's own
            progress = pd.read_csv(folder / "progress.csv")
            assert progress["training_iteration"].tolist() == list(range(1, ITERATIONS + 1)), (lam, killed_at, folder)
        assert resumed[lam]["eval"].keys() == expected[lam]["eval"].keys()
        for key, value in expected[lam]["eval"].items():
            if key not in ("wall_s", "setup_s"):  # timings
                assert resumed[lam]["eval"][key] == value, (lam, key)
        for name, tensor in expected[lam]["weights"].items():
            assert torch.equal(torch.as_tensor(resumed[lam]["weights"][name]), torch.as_tensor(tensor)), (lam, name)
