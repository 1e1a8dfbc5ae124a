"""A sweep on a real 2-node Ray cluster (two raylets on loopback), trials pinned to the second node."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)

SCRIPT = Path(__file__).with_name("two_node_sweep.py")


def test_sweep_runs_its_trials_on_the_second_node(tmp_path) -> None:
    sweep = {
        "name": "cluster",
        "population": "bandit-s1-hand",
        "lam": {"grid_search": [0.0, 0.5]},
        "model": {"hidden": 8},
        "ppo": {"rollout_per_partner": 16, "num_epochs": 1},
        "run": {"timesteps": 256, "resources": {"second_node": 1}},
    }
    config = tmp_path / "sweep.yaml"
    config.write_text(yaml.safe_dump(sweep))
    # A private temp dir: this cluster's sockets and logs stay apart from any other Ray on the machine.
    env = {**os.environ, "OMP_NUM_THREADS": "1", "RAY_ADDRESS": "", "RAY_TMPDIR": tempfile.mkdtemp(prefix="rt", dir="/tmp")}
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), str(config), str(tmp_path / "runs")], env=env, capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, (proc.stdout + proc.stderr)[-4000:]
    assert "--- 2/2 trials finished ---" in proc.stdout
    trials = sorted((tmp_path / "runs" / "cluster").glob("EgoTrainable_*"))
    assert len(trials) == 2
    for trial in trials:
        assert json.loads((trial / "seed=0" / "eval.json").read_text())["eval/mean/hand-train-0"] >= 0.0
        params = json.loads((trial / "params.json").read_text())
        assert params["run"]["resources"] == {"second_node": 1}
