"""Shared test set-up: one torch thread, the trained-ego fixtures, and the `slow` mark on every test that trains.

`make test-fast` (`pytest -m "not slow"`) must never train: each test that builds an RLlib
algorithm, runs Tune or starts a training subprocess carries `@pytest.mark.slow` (or its
file's `pytestmark`). A test reaching `ray_session` without the mark is marked here, with a
warning that names it, so a forgotten mark costs the fast loop nothing.
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("RAY_DEDUP_LOGS", "0")

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

# Fixtures that start Ray to train: a test using one, directly or through another fixture, trains.
TRAINING_FIXTURES = ("ray_session",)
# Session fixtures that train or fetch once: under `pytest -n 2 --dist loadgroup` (`make test`) the tests using one
# run on one worker, so it is built once, not once per worker.
SHARED_FIXTURES = ("bandit_egos", "blocks_ego", "lbf_ego", "short_human_cache")


@pytest.hookimpl(tryfirst=True)  # before pytest's own hook deselects by `-m`
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark `slow` (and warn about) every collected test that reaches a training fixture without the mark; group the
    tests of each shared session fixture for pytest-xdist."""
    for item in items:
        fixtures = getattr(item, "fixturenames", ())
        uses = [f for f in TRAINING_FIXTURES if f in fixtures]
        if uses and item.get_closest_marker("slow") is None:
            item.add_marker(pytest.mark.slow)
            item.warn(pytest.PytestWarning(f"{item.nodeid} trains (uses {uses[0]}) but has no @pytest.mark.slow; marked slow"))
        shared = [f for f in SHARED_FIXTURES if f in fixtures]
        if shared:
            item.add_marker(pytest.mark.xdist_group(shared[0]))


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

    config = experiment.load(
        "tune_configs/bandit_modular.yaml", ["name=egos", "population={grid_search: [bandit-s1-hand, bandit-s2-hand]}"]
    )
    results = run(config, storage=tmp_path_factory.mktemp("egos"))
    assert not results.errors
    return {r.config["population"]: TrainedEgo(str(trial_folders(r.path)[0]), r) for r in results}


@pytest.fixture(scope="session")
def blocks_ego(ray_session, tmp_path_factory) -> str:
    """A modular blocks ego (P1) trained briefly with the 3 training permutations: it knows the rules a little, the
    conventions hardly. Once per session: the posterior's and its controls' tests adapt the same ego."""
    from rllib_conv.common.run_folders import trial_folders
    from rllib_conv.pipelines.train import run
    from rllib_conv.training import experiment

    folder = tmp_path_factory.mktemp("blocks")
    overrides = [
        "name=blocks",
        "population=blocks-perm",
        "run.timesteps=4000",
        "ppo.rollout_per_partner=400",
        "ppo.minibatch_size=100",
    ]
    results = run(experiment.load("tune_configs/bandit_modular.yaml", overrides), storage=folder / "runs")
    assert not results.errors
    return str(trial_folders(results[0].path)[0])


@pytest.fixture(scope="session")
def lbf_ego(ray_session, tmp_path_factory) -> Path:
    """A tiny modular ego trained on lbf-heuristics (3 players, heads for H1/H2 teams); its trial folder. Once per
    session: the k-seat adaptation and evaluation tests read the same ego."""
    pytest.importorskip("lbforaging")
    import yaml

    from rllib_conv.cli import main
    from rllib_conv.common.run_folders import trial_folders

    root = tmp_path_factory.mktemp("lbf")
    config = root / "lbf3.yaml"
    tiny = {"name": "lbf3", "population": "lbf-heuristics", "model": {"hidden": 8}}
    config.write_text(yaml.safe_dump({**tiny, "ppo": {"rollout_per_partner": 50, "num_epochs": 1}, "run": {"timesteps": 200}}))
    assert main(["train", str(config), "--storage", str(root / "runs")]) == 0
    (trial,) = trial_folders(root / "runs" / "lbf3")
    return trial


@dataclass
class TrainedEgo:
    """A trained ego of a test fixture: its folder (`<trial>/seed=0`) and the Tune result of its trial."""

    path: str
    result: Any


@pytest.fixture(scope="session")
def short_human_cache(tmp_path_factory):
    """An Overcooked cache holding cramped_room's 2019 trajectories cut to the first 150 logged steps of each trial.

    Fetched through pip from the package registry (without it the tests using this fail, they
    do not skip); nothing derived from the human data is written outside the test's temporary folder.
    """
    import pandas as pd

    from rllib_conv.envs.overcooked import human_data

    folder = tmp_path_factory.mktemp("proxies-cache")
    human_data.fetch(folder)
    for path in human_data.convert(folder, ["cramped_room"]).values():
        frame = pd.read_parquet(path)
        frame[frame["t"] < 150].to_parquet(path, index=False)
    return folder
