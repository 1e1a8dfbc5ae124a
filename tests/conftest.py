"""Shared test set-up: one torch thread, quiet warnings from PettingZoo's Dict-observation checks."""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("RAY_DEDUP_LOGS", "0")

from dataclasses import dataclass
from typing import Any

import pytest


@pytest.fixture(scope="session")
def ray_session():
    """One local Ray for every test that builds an RLlib algorithm (2 CPUs, no dashboard)."""
    import ray

    if not ray.is_initialized():
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": {"OMP_NUM_THREADS": "1"}})
    yield ray
    ray.shutdown()


@pytest.fixture(scope="session")
def bandit_egos(ray_session, tmp_path_factory):
    """Modular egos (lam 0.5, the paper's 10 000 steps) on the bandit with 1 and 2 symmetric contexts.

    Trained once per session through the real Tune pipeline, two trials in parallel;
    returns {population name: TrainedEgo (the ego's folder and its trial's Tune result)}.
    """
    from rllib_conv.common.run_folders import trial_folders
    from rllib_conv.pipelines.train import run
    from rllib_conv.training import experiment

    raw = experiment.load(
        "tune_configs/bandit_modular.yaml", ["name=egos", "population={grid_search: [bandit-s1-hand, bandit-s2-hand]}"]
    )
    results = run(raw, storage=tmp_path_factory.mktemp("egos"))
    assert not results.errors
    return {r.config["population"]: TrainedEgo(str(trial_folders(r.path)[0]), r) for r in results}


@dataclass
class TrainedEgo:
    """A trained ego of a test fixture: its folder (`<trial>/seed=0`) and the Tune result of its trial."""

    path: str
    result: Any
