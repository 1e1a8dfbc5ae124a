"""Experiment configs: validation names the bad key, grids expand, overrides apply."""

from __future__ import annotations

import pytest
import yaml

from rllib_conv.common import config_files
from rllib_conv.pipelines.plans import PlanFile
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig
from rllib_conv.training import experiment
from rllib_conv.training.experiment import ExperimentConfig


def write(tmp_path, data) -> str:
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def test_shipped_configs_are_valid() -> None:
    from pathlib import Path

    files = sorted(Path("tune_configs").glob("*.yaml"))
    assert files
    for f in files:
        schema = (
            SelfPlayConfig if f.name.startswith("selfplay_") else PlanFile if f.name.startswith("plan_") else ExperimentConfig
        )
        assert config_files.validate(config_files.load(f, schema=schema), str(f), schema=schema)


def test_defaults_are_the_papers_per_game() -> None:
    exp = ExperimentConfig(population="x").resolve("blocks")
    assert (exp.model.hidden, exp.ppo.rollout_per_partner, exp.ppo.minibatch_size, exp.ppo.num_epochs, exp.run.timesteps) == (
        80,
        640,
        160,
        5,
        1_000_000,
    )
    exp = ExperimentConfig(population="x", model={"hidden": 12}).resolve("bandit")
    assert (exp.model.hidden, exp.ppo.num_epochs, exp.run.timesteps) == (12, 20, 10_000)


def test_a_rollout_shorter_than_the_games_minibatch_shrinks_the_default_minibatch_not_one_given() -> None:
    short = ExperimentConfig(population="x", ppo={"rollout_per_partner": 50}).resolve("lbf")  # lbf's minibatch: 250
    assert (short.ppo.rollout_per_partner, short.ppo.minibatch_size) == (50, 50)
    given = ExperimentConfig(population="x", ppo={"rollout_per_partner": 50, "minibatch_size": 40}).resolve("lbf")
    assert given.ppo.minibatch_size == 40
    assert ExperimentConfig(population="x").resolve("lbf").ppo.minibatch_size == 250


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"population": "p", "lamda": 0.5}, "lamda: Extra inputs are not permitted"),
        ({"population": "p", "ppo": {"lr": "fast"}}, "ppo.lr: Input should be a valid number"),
        ({"population": "p", "ppo": {"minibatch_size": 0}}, "ppo.minibatch_size: Input should be greater than 0"),
        ({"population": "p", "method": "meta"}, "method: Input should be 'modular', 'agg', 'no_task_logits', 'oracle' or 'maml'"),
        ({"population": "p", "method": "no_task_logits", "lam": 0.5}, "lam must be 0 for method 'no_task_logits'"),
        ({"population": "p", "env": "chess"}, "env: unknown env 'chess'"),
        ({"lam": 0.5}, "population: Field required"),
        ({"population": "p", "lam": -1}, "lam: Input should be greater than or equal to 0"),
        ({"population": "p", "name": "a b"}, "name: must be a non-empty folder name"),
        ({"population": "p", "lam": {"grid_search": [0.5, "x"]}}, "lam: Input should be a valid number"),
        ({"population": "p", "lam": {"grid_search": []}}, "lam: grid_search needs a non-empty list"),
    ],
)
def test_bad_configs_name_the_key(tmp_path, data, match) -> None:
    with pytest.raises(ValueError, match=match):
        experiment.load(write(tmp_path, data))


def test_grids_expand_to_every_combination(tmp_path) -> None:
    config = experiment.load(
        write(tmp_path, {"population": "p", "lam": {"grid_search": [0.0, 0.5]}, "seed": {"grid_search": [0, 1, 2]}})
    )
    assert sorted((v.lam, v.seed) for v in config.variants) == [(lam, s) for lam in (0.0, 0.5) for s in (0, 1, 2)]
    assert config.raw["lam"] == {"grid_search": [0.0, 0.5]}  # the grids kept for Tune
    assert experiment.checked(config.raw).variants == config.variants


def test_a_checked_config_is_a_copy_validated_once_and_blames_its_source() -> None:
    raw = {"population": "p", "lam": {"grid_search": [0.0, 0.5]}}
    config = config_files.checked(raw, ExperimentConfig, "plan")
    raw["lam"] = 2.0  # the caller's dict changing later changes nothing checked
    assert config.raw["lam"] == {"grid_search": [0.0, 0.5]} and [v.lam for v in config.variants] == [0.0, 0.5]
    assert config.first is config.variants[0] and isinstance(config.first, ExperimentConfig)
    with pytest.raises(ValueError, match=r"^plan: ppo\.lr: Input should be a valid number"):
        config_files.checked({"population": "p", "ppo": {"lr": "fast"}}, ExperimentConfig, "plan")
    with pytest.raises(ValueError, match=r"^--set lam=-1: lam: Input should be greater than or equal to 0"):
        config_files.with_sets({"population": "p"}, ["lam=-1"], ExperimentConfig)


def test_set_overrides_and_their_errors(tmp_path) -> None:
    raw = experiment.load(write(tmp_path, {"population": "p"}), ["ppo.lr=0.001", "lam=0.3", "run.timesteps=500"]).raw
    assert (raw["ppo"]["lr"], raw["lam"], raw["run"]["timesteps"]) == (0.001, 0.3, 500)
    with pytest.raises(ValueError, match="--set expects key=value"):
        experiment.load(write(tmp_path, {"population": "p"}), ["lam"])
    with pytest.raises(ValueError, match="ppo.num_epochs: Input should be a valid integer"):
        experiment.load(write(tmp_path, {"population": "p"}), ["ppo.num_epochs=many"])


@pytest.mark.parametrize(("schema", "key"), [(ExperimentConfig, "ppo.entropy_coeff"), (ZeroShotConfig, "task_entropy")])
def test_entropy_schedules_are_checked(schema, key) -> None:
    base = {"population": "p"} if schema is ExperimentConfig else {"runs": ["r"]}
    good = config_files.from_dict(base, [f"{key}=[[0, 0.05], [200000, 0.0]]"], schema=schema)
    assert config_files.validate(good, schema=schema)
    for bad in ("[[100, 0.05]]", "[[0, 0.05], [0, 0.0]]", "[]"):
        with pytest.raises(ValueError, match=f"{key}.*a schedule must be"):
            config_files.validate(config_files.from_dict(base, [f"{key}={bad}"], schema=schema), schema=schema)


def test_missing_and_broken_files(tmp_path) -> None:
    with pytest.raises(ValueError, match="does not exist"):
        experiment.load(tmp_path / "nope.yaml")
    (tmp_path / "bad.yaml").write_text("a: [1, 2")
    with pytest.raises(ValueError, match="not valid YAML"):
        experiment.load(tmp_path / "bad.yaml")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ValueError, match="expected a mapping"):
        experiment.load(tmp_path / "list.yaml")
