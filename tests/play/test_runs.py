"""Reading trained egos for play, and the real `rllib-conv play` command (started, queried, stopped with Ctrl-C)."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
import yaml

from rllib_conv import partners
from rllib_conv.play.ego_run import EgoRun, load_run, require_user_study
from rllib_conv.play.server import build_lobby


def test_a_trained_ego_gives_the_prior_and_its_seat(study_ego: Path, tmp_path: Path) -> None:
    run = load_run(study_ego)
    assert run.game == "bandit" and run.ego_seat == 1 and run.env_config == {"task": "user_study", "new_task": False}
    probs = run.prior(np.eye(3, dtype=np.float32), np.ones((3, 4), dtype=np.int8))
    assert probs.shape == (3, 4) and np.allclose(probs.sum(axis=1), 1) and (probs > 0).all()
    assert load_run(study_ego.parent).trial == study_ego  # an experiment folder with one trial is fine
    lobby = build_lobby(study_ego, out=tmp_path / "rec")
    assert lobby.agent.ego_seat == 1 and set(lobby.agent.priors) == {"train", "test"}
    assert lobby.run_info["test_prior"] == "oracle" and lobby.run_info["run"] == str(study_ego)


def test_runs_for_the_wrong_task_or_game_are_refused(study_ego: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="--test-run .* needs an ego trained on the user-study bandit's Test task .*bandit-user-study-newtask"):
        build_lobby(study_ego, test_run=study_ego, out=tmp_path / "rec")
    with pytest.raises(ValueError, match="trained on 'bandit', but --game is 'blocks'"):
        build_lobby(study_ego, game="blocks", out=tmp_path / "rec")
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


def test_the_play_command_serves_until_ctrl_c(study_ego: Path, tmp_path: Path) -> None:
    cmd = [sys.executable, "-m", "rllib_conv.cli", "play", str(study_ego), "--port", "0", "--out", str(tmp_path / "rec")]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        lines, url, deadline = [], None, time.monotonic() + 90
        while url is None and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if line.startswith("open http://127.0.0.1:"):
                url = line.split()[1]
        assert url, "".join(lines)
        assert any("recording to" in line for line in lines)
        with urllib.request.urlopen(url + "api/info", timeout=10) as r:
            info = json.loads(r.read())
        assert info["agent"] is True and info["game"] == "bandit"
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
