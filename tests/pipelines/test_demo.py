"""The README's main job (`make demo` = `rllib-conv demo`): it trains, then prints what the ego learned."""

from __future__ import annotations

import re

import pytest

from rllib_conv.common.resources import config_file
from rllib_conv.pipelines.demo import DEMO_CONFIG, demo
from rllib_conv.training import experiment

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)


def test_demo_trains_then_prints_returns_and_marginals(ray_session, tmp_path, capsys) -> None:
    demo(experiment.load(config_file(DEMO_CONFIG), ["name=demo", "run.timesteps=512"]), storage=tmp_path)
    out = capsys.readouterr().out
    header = re.search(r"Modular ego \(lam 0\.5\) after (\d+) env steps \((\d+) s\), run folder (\S+)", out)
    assert header, out
    assert int(header.group(1)) >= 512 and header.group(3).startswith(str(tmp_path))
    rows = [line for line in out.splitlines() if line.startswith("hand-train-")]
    assert len(rows) == 4  # one per training partner, with its expected return and sampled mean
    assert all(re.search(r"\d\.\d{3} \d\.\d{3} ± \d\.\d{3}$", row) for row in rows), rows
    contexts = out.split("Task module vs the true marginals")[1].splitlines()
    assert sum(bool(re.match(r"\s+[0-3]\s", line)) for line in contexts) == 4  # the bandit's 4 contexts
    assert re.search(r"L1 distance: \d\.\d{3} on the symmetric contexts", out)
