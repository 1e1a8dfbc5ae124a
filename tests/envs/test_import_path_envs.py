"""Games named by import path ("package.module:callable") work in every process, Tune trials included."""

from __future__ import annotations

import json

import pytest

from rllib_conv import envs, partners
from rllib_conv.pipelines.train import run
from rllib_conv.training import experiment

PATH = "rllib_conv.envs.bandit:CollaborativeBanditEnv"
# A game record named by path keeps what the record knows (its exact return); a bare env class has none.
RECORD_PATH = "rllib_conv.envs.bandit.record:BANDIT"


def test_an_import_path_names_a_game() -> None:
    env = envs.make(PATH, symmetric=1)
    assert type(env).__name__ == "CollaborativeBanditEnv" and env.num_contexts == 4
    with pytest.raises(ValueError, match=r"cannot import 'Nope' from module 'rllib_conv.envs.bandit'"):
        envs.make("rllib_conv.envs.bandit:Nope")
    with pytest.raises(ValueError, match=r"cannot import 'X' from module 'no_such_module'"):
        envs.make("no_such_module:X")


@pytest.mark.slow
def test_a_population_of_an_import_path_game_trains_through_tune(ray_session, tmp_path) -> None:
    # The Tune trial runs in another process, where nothing was `register`ed: the name alone must do.
    pop = partners.get("bandit-s1-hand").model_copy(update={"name": "by-path", "env": RECORD_PATH})
    pop.save(tmp_path / "pop.json")
    raw = {
        "name": "path",
        "population": str(tmp_path / "pop.json"),
        "model": {"hidden": 8},
        "ppo": {"rollout_per_partner": 16},
        "run": {"timesteps": 128},
    }
    results = run(experiment.checked(raw), storage=tmp_path / "runs")
    assert not results.errors
    evaluation = json.loads((tmp_path / "runs" / "path").glob("*/seed=0/eval.json").__next__().read_text())
    assert 0.0 <= evaluation["eval/exact/hand-train-0"] <= 1.0
