"""Shared by the play tests: a small ego trained on the user-study Train task, and headless chromium."""

from __future__ import annotations

from pathlib import Path

import pytest

CHROMIUM = "/usr/bin/chromium"


@pytest.fixture(scope="session")
def study_ego(ray_session, tmp_path_factory) -> Path:
    """A modular ego (lam 0.5) trained one PPO iteration (1536 steps, ~40 s) with the 24 user-study partners.

    Far from converged (its task module is near uniform): enough to be loaded, served and
    played with; the adaptation claims are tested on the agent with known priors.
    """
    from rllib_conv.common import config_files
    from rllib_conv.pipelines.train import run
    from rllib_conv.training.experiment import ExperimentConfig

    raw = config_files.from_dict(
        {
            "name": "play-ego",
            "population": "bandit-user-study",
            "method": "modular",
            "lam": 0.5,
            "run": {"timesteps": 1536, "eval_episodes": 20},
            "ppo": {"num_epochs": 5},
        },
        schema=ExperimentConfig,
    )
    results = run(raw, storage=tmp_path_factory.mktemp("play-egos"))
    assert not results.errors
    return Path(results[0].path)


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
