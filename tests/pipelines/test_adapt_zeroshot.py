"""Adapting to new partners and zero-shot coordination on a new task, through the real pipelines."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import torch

from rllib_conv import partners
from rllib_conv.common.config_files import checked
from rllib_conv.common.sealed import seal_file
from rllib_conv.modules import AGG_HEAD_ID, TASK_ID, ego_id
from rllib_conv.pipelines.adapt import CURVE_COLUMNS, adapt_curve, protocol, run_adaptation
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.zeroshot import run_zeroshot
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.evaluate import player_return
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.maml import META_MODULES, MetaTrainer, outer_update
from rllib_conv.training.weights import snapshot
from tests.helpers import digest


@pytest.mark.slow
def test_adaptation_adds_a_fresh_head_and_reaches_the_new_partner(bandit_egos, tmp_path) -> None:
    trial = Path(bandit_egos["bandit-s2-hand"].path)
    before = digest(trial)
    curve = adapt_curve(AdaptConfig(runs=[str(trial)]), str(trial), "hand-test-1")
    setup, load = curve.setup, curve.load
    assert setup.head_ids == [ego_id("hand-test-1")] and set(load) == {TASK_ID}  # a new head, the task module kept
    assert setup.exp.lam == 0.0 and setup.exp.ppo.num_epochs == 50 and setup.exp.ppo.rollout_per_partner == 16

    curves = run_adaptation(
        checked({"name": "a", "runs": [str(trial)], "partners": ["hand-test-1"]}, AdaptConfig),
        out=tmp_path,
        storage=tmp_path / "runs",
    )
    assert list(curves.columns) == CURVE_COLUMNS
    assert curves["steps"].tolist() == list(range(0, 241, 16))
    assert (curves["method"] == "modular").all() and (curves["lam"] == 0.5).all() and (curves["partner"] == "hand-test-1").all()
    # The task module's marginals already give 3/4 (two rule contexts right, two symmetric at 1/2).
    assert abs(curves["exact_return"].iloc[0] - 0.75) < 0.05
    assert curves["exact_return"].max() >= 0.9
    assert (tmp_path / "a.csv").is_file()
    assert digest(trial) == before  # the trained ego's files are untouched


@pytest.mark.slow
def test_curves_packed_together_equal_curves_run_one_at_a_time(bandit_egos, tmp_path) -> None:
    """Three curves as replicas of one algorithm give the curves each gives alone (float tolerance)."""
    trial = bandit_egos["bandit-s2-hand"].path
    raw = {"name": "p", "runs": [trial], "partners": ["hand-test-0", "hand-test-1", "hand-test-2"], "steps": 64, "episodes": 50}
    packed = run_adaptation(checked(raw, AdaptConfig), out=tmp_path / "packed", storage=tmp_path / "runs")
    alone = run_adaptation(
        checked({**raw, "name": "a", "max_pack": 1}, AdaptConfig), out=tmp_path / "alone", storage=tmp_path / "runs"
    )
    assert (
        len(list((tmp_path / "runs" / "adapt-p").glob("AdaptTrainable_*")))
        < len(list((tmp_path / "runs" / "adapt-a").glob("AdaptTrainable_*")))
        == 3
    )
    # Float tolerance: the bandit's learner runs on the distinct contexts of all packed replicas' rows at once
    # (`StackedEgoMultiRLModule._forward_situations`), so a packed curve's matmuls have other shapes, and other
    # rounding, than its lone run's; 64 Adam steps carry that to ~4e-5 of a return.
    pd.testing.assert_frame_equal(packed, alone, rtol=1e-4, atol=1e-5)
    assert packed["exact_return"].nunique() > 3  # the curves moved


@pytest.mark.slow
def test_bandit_curves_without_sampled_episodes_keep_their_exact_returns(bandit_egos, tmp_path) -> None:
    """`episodes: 0` plays no evaluation episodes: the same exact returns (evaluation draws nothing training uses), no sampled ones."""
    trial = bandit_egos["bandit-s2-hand"].path
    raw = {"name": "e", "runs": [trial], "partners": ["hand-test-0", "hand-test-1"], "steps": 48, "episodes": 50}
    sampled = run_adaptation(checked(raw, AdaptConfig), out=tmp_path / "sampled", storage=tmp_path / "runs")
    exact = run_adaptation(
        checked({**raw, "name": "x", "episodes": 0}, AdaptConfig), out=tmp_path / "exact", storage=tmp_path / "runs"
    )
    assert exact["mean_return"].isna().all() and exact["stderr"].isna().all() and sampled["mean_return"].notna().all()
    pd.testing.assert_series_equal(exact["exact_return"], sampled["exact_return"])
    assert sampled["exact_return"].nunique() > 2  # the curves moved


def test_no_sampled_episodes_is_refused_where_no_exact_return_exists() -> None:
    scripted = partners.get("hanabi-scripted").partners[0].build()
    with pytest.raises(ValueError, match="episodes=0 .* 'hanabi' needs episodes >= 1"):
        player_return(scripted, "hanabi", {}, scripted, "player_0", "player_1", episodes=0)
    # Blocks has one: two permutation partners are scored exactly with no episode played.
    blocks = partners.get("blocks-perm").partners[0].build()
    score = player_return(blocks, "blocks", {}, blocks, "player_0", "player_1", episodes=0)
    assert math.isnan(score["mean"]) and 0.0 <= score["exact"] <= 20.0


@pytest.mark.parametrize(
    ("env", "population", "set_episodes", "expected"),
    [
        ("overcooked", "overcooked-cramped_room-cooks", None, 50),
        ("blocks", "blocks-perm", None, 200),
        ("overcooked", "overcooked-cramped_room-cooks", 7, 7),
    ],
)
def test_episodes_per_evaluation_default_to_the_games_protocol(env, population, set_episodes, expected) -> None:
    trained = ExperimentConfig(env=env, population=population)
    cfg = AdaptConfig(runs=["x"], episodes=set_episodes)
    every, steps, episodes = protocol(cfg, trained)
    assert episodes == expected and (every, steps) == ((1_600, 16_000) if env == "overcooked" else (640, 25_600))


@pytest.mark.slow
def test_adapting_drops_the_head_penalty(bandit_egos, tmp_path) -> None:
    import shutil

    import yaml

    trial = tmp_path / "trial"
    shutil.copytree(bandit_egos["bandit-s2-hand"].path, trial)
    trained = yaml.safe_load((trial / "config.yaml").read_text())
    (trial / "config.yaml").write_text(yaml.safe_dump({**trained, "head_l2": 0.1}))
    seal_file(trial / "config.yaml")  # edited on purpose: sealed again, as training writes it
    curve = adapt_curve(AdaptConfig(runs=[str(trial)]), str(trial), "hand-test-1")
    assert curve.trained.head_l2 == 0.1 and curve.setup.exp.head_l2 == 0.0  # adapting is plain PPO, as in the paper


@pytest.mark.slow
def test_scratch_starts_from_nothing(bandit_egos, tmp_path) -> None:
    trial = bandit_egos["bandit-s2-hand"].path
    curve = adapt_curve(AdaptConfig(runs=[trial], method="scratch"), trial, "hand-test-0")
    assert curve.load == {} and curve.setup.head_ids == [AGG_HEAD_ID]
    curves = run_adaptation(
        checked({"name": "s", "runs": [trial], "partners": ["hand-test-0"], "method": "scratch", "steps": 32}, AdaptConfig),
        out=tmp_path,
        storage=tmp_path / "runs",
    )
    assert curves["exact_return"].iloc[0] < 0.5  # a fresh network knows neither rules nor conventions
    assert (curves["method"] == "scratch").all()


@pytest.mark.slow
def test_zero_shot_composes_new_task_module_with_test_partner_heads(bandit_egos, tmp_path) -> None:
    trial = bandit_egos["bandit-s1-hand"].path
    table = run_zeroshot(
        checked({"name": "z", "runs": [trial], "head_steps": 1024, "task_steps": 4096}, ZeroShotConfig),
        out=tmp_path,
        storage=tmp_path / "runs",
    )
    assert sorted(table["partner"]) == [f"hand-test-{k}" for k in range(4)]
    assert (table["exact_return"] >= 0.9).all(), table
    assert (tmp_path / "z.csv").is_file()


def test_zero_shot_refuses_non_modular_runs(tmp_path) -> None:
    import yaml

    from rllib_conv.pipelines.zeroshot import zeroshot_plan

    trial = tmp_path / "trial"
    (trial / "checkpoint_000000").mkdir(parents=True)
    (trial / "config.yaml").write_text(yaml.safe_dump(ExperimentConfig(population="bandit-s1-hand", method="agg").model_dump()))
    with pytest.raises(ValueError, match="not modular"):
        zeroshot_plan(ZeroShotConfig(runs=[str(trial)]), str(trial))


@pytest.mark.parametrize("method", ["modular", "no_task_logits"])
def test_zero_shot_steps_carry_their_settings(method: str) -> None:
    from rllib_conv.pipelines.zeroshot import step_experiments

    modular = method == "modular"
    trained = ExperimentConfig(
        population="blocks-perm", method=method, lam=0.5 if modular else 0.0, head_l2=0.01 if modular else 0.0
    )
    cfg = ZeroShotConfig(runs=["-"], head_lam=0.3, task_z_lr_scale=0.2, task_entropy=0.01)
    steps = step_experiments(trained, cfg)
    heads, task = steps["heads"], steps["task"]
    assert heads.freeze == ["task"] and task.freeze == ["heads"]
    # Only learned task logits have a regulariser; unset weights are the run's lam.
    assert (heads.lam, task.lam) == ((0.3, 0.5) if method == "modular" else (0.0, 0.0))
    defaults = step_experiments(trained, ZeroShotConfig(runs=["-"]))
    assert defaults["heads"].lam == defaults["task"].lam == trained.lam
    assert (heads.z_lr_scale, task.z_lr_scale) == (1.0, 0.2)
    assert (heads.ppo.entropy_coeff, task.ppo.entropy_coeff) == (trained.ppo.entropy_coeff, 0.01)
    # Test heads are penalised like the training heads; frozen heads in step 2 are not.
    assert (heads.head_l2, task.head_l2) == (trained.head_l2, 0.0)
    assert trained.lam == (0.5 if method == "modular" else 0.0) and trained.freeze == []  # the run's config is untouched


def test_outer_update_by_hand() -> None:
    theta = {"task": {"w": torch.tensor([1.0, 2.0])}}
    adapted = {"task": {"w": torch.tensor([3.0, -2.0])}}
    assert outer_update(theta, adapted, 0.25)["task"]["w"].tolist() == [1.5, 1.0]


@pytest.mark.slow
def test_one_maml_outer_step_moves_weights_by_outer_step_times_adaptation(ray_session) -> None:
    exp = ExperimentConfig(
        population="bandit-s2-hand", method="maml", model={"hidden": 8}, ppo={"rollout_per_partner": 16, "num_epochs": 2}
    )
    setup = resolve(exp)
    algo = build_ppo_config(setup).build_algo()
    try:
        learner_module = algo.learner_group._learner.module
        trainer = MetaTrainer(algo, [e.name for e in setup.train], inner_iterations=4, outer_step=0.25)
        theta = snapshot(learner_module, META_MODULES)
        adapted = {}
        real_train = algo.train

        def train_and_record():
            result = real_train()
            adapted.update(snapshot(learner_module, META_MODULES))  # the weights after the latest inner iteration
            return result

        algo.train = train_and_record
        result = trainer.step()
        expected = outer_update(theta, adapted, 0.25)
        after = snapshot(learner_module, META_MODULES)
        for mid in META_MODULES:
            for k in theta[mid]:
                torch.testing.assert_close(after[mid][k], expected[mid][k])
                assert not torch.equal(after[mid][k], adapted[mid][k]) or torch.equal(theta[mid][k], adapted[mid][k])
        # The env runners got the meta-weights too.
        runner = snapshot(algo.env_runner.module, META_MODULES)
        for mid in META_MODULES:
            for k in theta[mid]:
                torch.testing.assert_close(runner[mid][k], after[mid][k])
        # The inner loop played the first partner only.
        sampled = result["env_runners"]["num_module_steps_sampled_lifetime"]
        others = [sampled.get(f"partner@{e.name}#0", 0) for e in setup.train[1:]]  # replica 0's partner modules
        assert sampled[f"partner@{setup.train[0].name}#0"] >= 4 * 16 - 8 and max(others) <= 8
    finally:
        algo.stop()


@pytest.mark.slow
def test_maml_trains_through_the_pipeline(ray_session, tmp_path) -> None:
    from rllib_conv.pipelines.train import run

    raw = {
        "name": "maml",
        "population": "bandit-s2-hand",
        "method": "maml",
        "model": {"hidden": 8},
        "ppo": {"rollout_per_partner": 16, "num_epochs": 1},
        "run": {"timesteps": 256},
    }
    result = run(checked(raw, ExperimentConfig), storage=tmp_path)[0]
    assert result.error is None and result.metrics["env_steps"] >= 256
    assert np.isfinite(result.metrics["eval/marginal_distance/all"])
