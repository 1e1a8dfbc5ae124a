"""Reading trained egos for play, and the real `rllib-conv play RUN` (started, queried, stopped with Ctrl-C)."""

from __future__ import annotations

import shutil
from pathlib import Path

import httpx
import numpy as np
import pytest
import yaml

from rllib_conv import partners
from rllib_conv.play.conditions import build_settings
from rllib_conv.play.ego_run import EgoRun, load_run, require_user_study
from tests.play.servers import ADMIN_TOKEN

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)


def test_a_trained_ego_gives_the_prior_and_its_seat(study_ego: Path, tmp_path: Path) -> None:
    run = load_run(study_ego)
    assert run.game == "bandit" and run.ego_seat == 1 and run.env_config == {"task": "user_study", "new_task": False}
    probs = run.prior(np.eye(3, dtype=np.float32), np.ones((3, 4), dtype=np.int8))
    assert probs.shape == (3, 4) and np.allclose(probs.sum(axis=1), 1) and (probs > 0).all()
    assert load_run(study_ego.parent).trial == run.trial  # an experiment folder with one trial is fine
    settings = build_settings(study_ego, conditions="agent,human")
    agent = settings.condition("agent").agent
    assert agent.ego_seat == 1 and set(agent.priors) == {"train", "test"} and settings.game == "bandit"
    assert (
        agent.description.startswith("modular ego (lam 0.5) trained with bandit-user-study")
        and "Test task: the true marginals" in agent.description
    )
    two = build_settings(agents=[f"ours={study_ego}", "baseline=oracle"], conditions="ours,baseline,human")
    assert [c.kind for c in two.conditions] == ["agent", "agent", "human"]


def test_the_posterior_adapter_reads_the_runs_heads_and_training_partners(study_ego: Path) -> None:
    agent = build_settings(study_ego, adapter="posterior").condition("agent").agent
    assert len(agent.conventions.models) == len(agent.conventions.known) == 24  # the user-study training pairs
    assert "a posterior over its training partners' conventions (not in the paper)" in agent.description
    assert build_settings(study_ego).condition("agent").agent.conventions is None  # the paper's agent by default
    with pytest.raises(ValueError, match="--adapter posterior: --agent baseline=oracle has no training partners' heads"):
        build_settings(agents=["baseline=oracle"], adapter="posterior")
    with pytest.raises(
        ValueError, match="--adapter must be one of \\['fresh', 'posterior'\\] \\(or the old spelling 'table'\\), got 'bayes'"
    ):
        build_settings(study_ego, adapter="bayes")


def test_runs_for_the_wrong_task_or_game_are_refused(study_ego: Path, tmp_path: Path) -> None:
    with pytest.raises(
        ValueError,
        match="--test-run agent .* needs an ego trained on the user-study bandit's Test task .*bandit-user-study-newtask",
    ):
        build_settings(study_ego, test_runs=[str(study_ego)])
    with pytest.raises(ValueError, match="trained on 'bandit', but --game is 'blocks'"):
        build_settings(study_ego, game="blocks")
    run = load_run(study_ego)
    other = EgoRun(run.trial, run.exp, partners.get("bandit-s2-hand"), run.prior)
    with pytest.raises(ValueError, match="RUN .* was trained on bandit with \\{'symmetric': 2, 'new_task': False\\}"):
        require_user_study(other, new_task=False, what="RUN")


def test_folders_that_are_not_one_usable_trial_are_refused(study_ego: Path, tmp_path: Path) -> None:
    two = tmp_path / "two"
    for name in ("a", "b"):
        (two / name).mkdir(parents=True)
        shutil.copy(study_ego / "config.yaml", two / name / "config.yaml")
    with pytest.raises(ValueError, match="RUN .* holds 2 trained-ego trials \\(a, b\\); pass one trial folder"):
        load_run(two)
    with pytest.raises(ValueError, match="^RUN: .*checkpoint"):
        load_run(two / "a")  # a config but no checkpoint
    with pytest.raises(ValueError, match="^RUN: .*neither a trained-ego trial folder"):
        load_run(tmp_path)
    cfg = yaml.safe_load((study_ego / "config.yaml").read_text())
    (two / "a" / "config.yaml").write_text(yaml.safe_dump({**cfg, "method": "no_task_logits", "lam": 0.0}))
    with pytest.raises(ValueError, match="'no_task_logits' ego: its task module is not a marginal estimate"):
        load_run(two / "a")


def test_the_play_command_serves_a_trained_ego_until_ctrl_c(study_ego: Path, study_process, tmp_path: Path) -> None:
    server = study_process([str(study_ego), "--port", "0", "--out", str(tmp_path / "study")])
    assert any("admin page: http://127.0.0.1:" in line for line in server.lines)
    assert not [line for line in server.lines if "Deprecation" in line], server.lines  # RLlib's, while the ego loads (issue 47)
    with httpx.Client(base_url=server.url, timeout=10) as c:
        info = c.get("/api/info").json()
        p = c.post("/api/participants", json={"consent": True, "participant": "p1"}).json()
        view = c.post("/api/move", json={"token": p["token"], "step": 0, "arm": 1}).json()
        status = c.get("/api/admin/status", headers={"Authorization": f"Bearer {ADMIN_TOKEN}"}).json()
    assert info["game"] == "bandit" and view["played"] == 1 and view["partner"] == "agent"
    assert not [
        w for w in ("modular", "lam", "EgoTrainable", "bandit-user-study") if w in str(info) + str(view)
    ]  # no internals for participants
    assert status["conditions"][0]["description"].startswith("modular ego (lam 0.5) trained with bandit-user-study")
    assert server.interrupt() == 130  # Ctrl-C: a graceful stop, then the usual status of an interrupt
    assert (tmp_path / "study" / "study.sqlite3").exists()
