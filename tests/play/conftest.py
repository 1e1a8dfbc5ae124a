"""Shared by the play tests: a small trained ego, a blocks convention source, study servers (in a thread or a process), headless chromium."""

from __future__ import annotations

from pathlib import Path

import pytest

from rllib_conv import envs
from rllib_conv.envs.blocks.keys import blocks_observation
from rllib_conv.partners.blocks import TRAIN_PERMUTATIONS, BlocksLeader, PermutationPartner
from rllib_conv.play.conditions import StudySettings
from rllib_conv.play.convention_agent import ConventionSource
from rllib_conv.play.server import StudyServer
from rllib_conv.play.store import DB_FILE
from tests.play.servers import ADMIN_TOKEN, StudyProcess

CHROMIUM = "/usr/bin/chromium"


@pytest.fixture
def blocks_conventions() -> ConventionSource:
    """`--adapter posterior` on blocks without a trained ego: the 3 training permutations as the posterior's models, their leaders as the heads."""
    models = [PermutationPartner(f"train-{i}", list(p)) for i, p in enumerate(TRAIN_PERMUTATIONS)]
    leaders = [BlocksLeader(f"leader-{i}", list(p)) for i, p in enumerate(TRAIN_PERMUTATIONS)]
    return ConventionSource(models, leaders, blocks_observation, envs.best_response("blocks", {}, "player_0"))


@pytest.fixture(scope="session")
def study_ego(ray_session, tmp_path_factory) -> Path:
    """A modular ego (lam 0.5) trained one PPO iteration (1536 steps, ~40 s) with the 24 user-study partners.

    Far from converged (its task module is near uniform): enough to be loaded, served and
    played with; the adaptation claims are tested on the agent with known priors.
    """
    from rllib_conv.common import config_files
    from rllib_conv.common.run_folders import trial_folders
    from rllib_conv.pipelines.train import run
    from rllib_conv.training.experiment import ExperimentConfig

    config = config_files.checked(
        {
            "name": "play-ego",
            "population": "bandit-user-study",
            "method": "modular",
            "lam": 0.5,
            "run": {"timesteps": 1536, "eval_episodes": 20},
            "ppo": {"num_epochs": 5},
        },
        ExperimentConfig,
    )
    results = run(config, storage=tmp_path_factory.mktemp("play-egos"))
    assert not results.errors
    return trial_folders(results[0].path)[0]  # the trained ego's folder, wherever the trial keeps it


@pytest.fixture
def serve(tmp_path: Path):
    """Start study servers in background threads, each on a free port and its own database; stop them at the end."""
    servers: list[StudyServer] = []

    def start(settings: StudySettings, db: Path | None = None, **options) -> StudyServer:
        db = db or tmp_path / f"study{len(servers)}" / DB_FILE
        srv = StudyServer(settings, db, port=0, admin_token=ADMIN_TOKEN, **options)
        srv.start()
        servers.append(srv)
        return srv

    yield start
    for srv in servers:
        srv.stop()


@pytest.fixture
def study_process():
    """Start `rllib-conv play` processes; each is killed at the end if still running."""
    procs: list[StudyProcess] = []

    def start(args: list[str]) -> StudyProcess:
        procs.append(StudyProcess(args))
        return procs[-1]

    yield start
    for proc in procs:
        proc.close()


@pytest.fixture(scope="module")
def browser():
    """Debian's chromium, headless, driven by Playwright (never Playwright's own download)."""
    if not Path(CHROMIUM).exists():
        pytest.fail(f"{CHROMIUM} is missing: the browser tests need Debian's chromium (`make chromium` installs it)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=["--headless", "--no-sandbox"])
        yield b
        b.close()
