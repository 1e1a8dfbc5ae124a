"""TrajeDi (`trajectory_diversity`): MEP's joint trial with a trajectory-JSD bonus; beta 0 equals pairs trained alone,
a positive beta makes the pairs' conventions differ more, multi-step games train, bad values are one clear error."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from ray.rllib.core import ALL_MODULES

from rllib_conv.cli import main
from rllib_conv.common import config_files
from rllib_conv.envs.bandit import good_arms, paper_prizes
from rllib_conv.learners.marginal_learner import TRAJECTORY_DIVERSITY_KEY
from rllib_conv.learners.settings import LearnerSettings
from rllib_conv.pipelines.selfplay import build_joint_config, joint_description, selfplay_score, split_pairs, trial_pairs
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from tests.pipelines.test_mep import TRAJEDI_YAML, greedy_arms, joint_config


def trajedi_config(**overrides) -> SelfPlayConfig:
    return joint_config(TRAJEDI_YAML, **overrides)


def test_each_split_is_one_trial_and_the_learner_gets_the_weight() -> None:
    cfg = trajedi_config(train_pairs=3, test_pairs=2, trajectory_discount=0.8)
    assert cfg.joint and trial_pairs(cfg) == [0, 3] and split_pairs(cfg, 3) == [3, 4]
    settings = LearnerSettings(**build_joint_config(cfg).learner_config_dict)
    assert settings.trajectory_diversity == cfg.trajectory_diversity and settings.trajectory_discount == 0.8
    assert settings.population_entropy == 0.0
    assert settings.populations["seat@player_1"] == ["seat@player_1#0", "seat@player_1#1", "seat@player_1#2"]
    # Unset discount: the learner's default; MEP and TrajeDi combine (two bonuses), and say so.
    both = trajedi_config(population_entropy=0.5)
    settings = LearnerSettings(**build_joint_config(both).learner_config_dict)
    assert settings.trajectory_discount == LearnerSettings.trajectory_discount and settings.population_entropy == 0.5
    assert "(MEP) and trajectory diversity" in joint_description(both) and "(TrajeDi)" in joint_description(both)


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (["trajectory_diversity=-0.5"], "trajectory_diversity: Input should be greater than or equal to 0"),
        (["trajectory_diversity=lots"], "trajectory_diversity: Input should be a valid number"),
        (["trajectory_discount=1.5"], "trajectory_discount: Input should be less than or equal to 1"),
        (["trajectory_diversity=null", "trajectory_discount=0.9"], "trajectory_discount is TrajeDi's: set trajectory_diversity"),
        (["fcp=true"], "fcp and trajectory_diversity cannot be combined"),
    ],
)
def test_bad_values_are_one_clear_error(sets, message, capsys, tmp_path) -> None:
    argv = ["partners", "train", TRAJEDI_YAML, "--out", str(tmp_path / "pops"), "--storage", str(tmp_path / "runs")]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and err[0].startswith("rllib-conv: error: "), err
    assert not any(tmp_path.iterdir())


def test_help_lists_the_keys_from_the_schema(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["partners", "train", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    for key in ("trajectory_diversity", "trajectory_discount"):
        assert " ".join(SelfPlayConfig.model_fields[key].description.split()) in out


def _train(cfg: SelfPlayConfig, iterations: int) -> tuple[list[list[int]], list[float], float]:
    """Each pair's partner-seat greedy arm per context, each pair's greedy self-play score, the last logged JSD of that seat."""
    algo = build_joint_config(cfg).build_algo()
    try:
        for _ in range(iterations):
            result = algo.train()
        module = algo.env_runner.module
        arms = [greedy_arms(module, k)[1] for k in range(cfg.train_pairs)]
        scores = [selfplay_score(module, cfg, 200, seed=7, member=k) for k in range(cfg.train_pairs)]
        jsd = float(result["learners"][ALL_MODULES][f"{TRAJECTORY_DIVERSITY_KEY}/seat@player_1"])
    finally:
        algo.stop()
    return arms, scores, jsd


@pytest.mark.slow
def test_a_bonus_makes_the_pairs_conventions_differ_more(ray_session) -> None:
    """Obvious answer: 4 contexts with two good arms each, two pairs, the same seeds with beta 0.2 and 0. Without the
    bonus the pairs share a good arm in a context by chance (1/2 each); with it they share fewer, stay on good arms
    and coordinated, and the JSD of their partner seats is higher at no seed lower."""
    good = good_arms(paper_prizes(4))
    distinct, jsd = {0.2: 0, 0.0: 0}, {0.2: [], 0.0: []}
    for seed in (0, 10, 20, 30):
        for beta in (0.2, 0.0):
            arms, scores, last_jsd = _train(trajedi_config(train_pairs=2, test_pairs=0, seed=seed, trajectory_diversity=beta), 30)
            assert min(scores) >= 0.95, (seed, beta, scores)
            assert all(a in good[c] for pair in arms for c, a in enumerate(pair)), (seed, beta, arms)
            distinct[beta] += sum(a != b for a, b in zip(*arms))
            jsd[beta].append(last_jsd)
    print(f"contexts where the pairs differ: {distinct}; last JSD per seed: {jsd}")
    assert distinct[0.2] > distinct[0.0], distinct
    assert all(b >= a - 0.02 for a, b in zip(jsd[0.0], jsd[0.2])) and np.mean(jsd[0.2]) > np.mean(jsd[0.0]) + 0.05, jsd


@pytest.mark.slow
def test_multi_step_episodes_train(ray_session) -> None:
    """Blocks (episodes of many moves, cut by the sample's end): the JSD is estimated on the segments, finite and in
    [0, log N] up to sampling, and the bonus trains."""
    raw = config_files.load("tune_configs/selfplay_blocks.yaml", [], schema=SelfPlayConfig)
    raw.update(
        {"train_pairs": 2, "test_pairs": 0, "trajectory_diversity": 0.5, "trajectory_discount": 0.9, "model": {"hidden": 16}}
    )
    raw["ppo"] = {**raw["ppo"], "rollout_per_partner": 200, "minibatch_size": 100, "num_epochs": 1}
    cfg = SelfPlayConfig.model_validate(raw).resolve()
    algo = build_joint_config(cfg).build_algo()
    learner = algo.learner_group._learner  # local: the same process
    module, episode_columns, seen = learner.module, learner.plain_episode_columns, []
    learner.plain_episode_columns = lambda data, lengths: seen.append(lengths) or episode_columns(data, lengths)
    try:
        before = {mid: module[mid].pi_out[0].weight.detach().clone() for mid in module.keys()}
        result = algo.train()
    finally:
        algo.stop()
    assert max(n for lengths in seen[0].values() for n in lengths) > 1  # episodes of several moves
    for mid, weight in before.items():
        assert not torch.equal(weight, module[mid].pi_out[0].weight)
    for seat in ("seat@player_0", "seat@player_1"):
        value = float(result["learners"][ALL_MODULES][f"{TRAJECTORY_DIVERSITY_KEY}/{seat}"])
        assert math.isfinite(value) and -0.1 < value < math.log(2) + 0.1, value
