"""`BatchedEnvRunner` trains exactly as RLlib's episode path does: same train batches, same weights, same metrics.

RLlib's path (`LeanEnvRunner`: RLlib's sampling, our metric counting) is the reference, set
here on the built config; no setting selects it in training.

On every game: the bandit (parallel, one step), blocks (turn-based: a move waits for the
mover's next observation) and Hanabi (turn-based, copies of different lengths). Batches of
100 env steps per partner cut episodes between samples, so chunks and moves hanging across
a cut are covered. Packed egos and self-play pairs (plain modules, actions drawn from the
global generator) both.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.learner.training_data import TrainingData
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.evaluation.postprocessing import Postprocessing

from rllib_conv.common import config_files
from rllib_conv.learners.packed.rollout import Rollout
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.pipelines.selfplay import build_selfplay_config
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.training.algorithm import Replica, build_ppo_config
from rllib_conv.training.batched_env_runner import BatchedEnvRunner
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.lean_env_runner import LeanEnvRunner

COLUMNS = (Columns.ACTIONS, Columns.ACTION_LOGP, Postprocessing.ADVANTAGES, Postprocessing.VALUE_TARGETS)
# What the env runners report per iteration that the two paths must agree on.
METRICS = (
    "num_env_steps_sampled",
    "num_episodes",
    "episode_return_mean",
    "episode_len_mean",
    "agent_episode_returns_mean",
    "module_episode_returns_mean",
    "num_module_steps_sampled",
)


def _runner(config, batched: bool):
    """`config` sampled by the batched runner (training's) or by RLlib's episode path (the reference)."""
    return config if batched else config.env_runners(env_runner_cls=LeanEnvRunner)


def _algorithm(batched: bool, population: str = "bandit-s2-hand", seeds: tuple[int, ...] = (3, 8), **run):
    ppo = {} if population.startswith("bandit") else {"rollout_per_partner": 100, "minibatch_size": 50}
    replicas = [
        Replica(resolve(ExperimentConfig(population=population, lam=0.5, seed=s, model={"hidden": 8}, ppo=ppo, run=run)))
        for s in seeds
    ]
    return _runner(build_ppo_config(replicas), batched).build_algo()


def _train_batches(algo, samples: int) -> list:
    learner = algo.learner_group._learner
    return [learner._make_batch_if_necessary(TrainingData(episodes=algo.env_runner.sample())) for _ in range(samples)]


@pytest.mark.parametrize("population", ["bandit-s2-hand", "blocks-perm", "hanabi-scripted"])
@pytest.mark.slow
def test_batched_sampling_gives_rllibs_batches_weights_and_metrics(ray_session, population: str) -> None:
    rllib, batched = _algorithm(False, population), _algorithm(True, population)
    try:
        assert type(rllib.env_runner) is LeanEnvRunner and type(batched.env_runner) is BatchedEnvRunner
        results = [[algo.train()["env_runners"] for _ in range(2)] for algo in (rllib, batched)]
        for theirs, ours in zip(*results):
            for key in METRICS:
                assert ours[key] == pytest.approx(theirs[key]), key
        weights = [algo.learner_group._learner.module[STACK_ID].state_dict() for algo in (rllib, batched)]
        for name, value in weights[0].items():
            assert torch.equal(value, weights[1][name]), name
        # Three samples in a row: the env copies, the partner mapping, every replica's generator and the episodes cut between samples carry over.
        for theirs, ours in zip(_train_batches(rllib, 3), _train_batches(batched, 3)):
            heads = set(ours.policy_batches)
            assert heads == set(batched.learner_group._learner.module.head_ids())
            assert heads <= set(theirs.policy_batches)  # theirs also holds the fixed partners' rows, which never train
            for mid in heads:
                mine, rl = ours.policy_batches[mid], theirs.policy_batches[mid]
                for key in ("observations", "action_mask"):
                    assert torch.equal(torch.as_tensor(mine[Columns.OBS][key]), torch.as_tensor(rl[Columns.OBS][key])), (mid, key)
                for col in COLUMNS:
                    assert torch.equal(
                        torch.as_tensor(mine[col]), torch.as_tensor(rl[col]).to(torch.as_tensor(mine[col]).dtype)
                    ), (mid, col)
    finally:
        rllib.stop()
        batched.stop()


def _selfplay(batched: bool, game: str, seed: int = 4):
    small = ["ppo.rollout_per_partner=200", "ppo.minibatch_size=50", "model.hidden=16"] if game != "bandit" else []
    raw = config_files.load(f"tune_configs/selfplay_{game}.yaml", [*small, f"seed={seed}"], schema=SelfPlayConfig)
    return _runner(build_selfplay_config(SelfPlayConfig.model_validate(raw).resolve()), batched).build_algo()


def _stepped_in_arrival_order(episode: MultiAgentEpisode) -> Any:
    """`get_agents_that_stepped` as an ordered set: the env's observation order, whatever the hash seed."""
    return dict.fromkeys(episode.get_observations(-1)).keys()


def _agents_in_arrival_order(episode: MultiAgentEpisode) -> Any:
    """`agent_ids` as an ordered set: the order the agents joined the episode."""
    return dict.fromkeys(episode.agent_episodes).keys()


@pytest.mark.parametrize("game", ["bandit", "blocks", "hanabi"])
@pytest.mark.slow
def test_batched_selfplay_gives_rllibs_weights_and_metrics(ray_session, monkeypatch, game: str) -> None:
    # RLlib draws the modules' actions, and reads a shared seat's rows, in the order of a set of
    # agent IDs, which follows the process's string hash seed; in arrival order they are in the
    # order the batched runner uses (the same in every process).
    monkeypatch.setattr(MultiAgentEpisode, "get_agents_that_stepped", _stepped_in_arrival_order)
    monkeypatch.setattr(MultiAgentEpisode, "agent_ids", property(_agents_in_arrival_order))
    runs = []
    for batched in (False, True):  # one after the other: building an algorithm seeds torch's global generator
        algo = _selfplay(batched, game)
        try:
            assert type(algo.env_runner) is (BatchedEnvRunner if batched else LeanEnvRunner)
            metrics, weights = [], []
            for _ in range(2):
                metrics.append(algo.train()["env_runners"])
                module = algo.learner_group._learner.module
                weights.append({(mid, name): v.clone() for mid in module.keys() for name, v in module[mid].state_dict().items()})
            runs.append((metrics, weights))
        finally:
            algo.stop()
    (rllib_metrics, rllib_weights), (metrics, weights) = runs
    for theirs, ours in zip(rllib_metrics, metrics):
        for key in METRICS:
            assert ours[key] == pytest.approx(theirs[key]), key
    # Hanabi's one module plays both seats: in the chunk of an episode continued from the last
    # sample RLlib lists the seats in the order its cut episode rebuilds them, the batched runner
    # in the order they joined, so from the second update on its minibatches differ.
    for theirs, ours in zip(rllib_weights[:1] if game == "hanabi" else rllib_weights, weights):
        assert set(ours) == set(theirs)
        for key, value in theirs.items():
            assert torch.equal(value, ours[key]), key


@pytest.mark.slow
def test_it_samples_rllibs_way_where_it_cannot_batch(ray_session) -> None:
    restarting = _algorithm(True, seeds=(0,), restart_failed_sub_environments=True)
    bandit = _algorithm(True)
    try:
        # Envs that RLlib recreates when they raise: RLlib's episodes.
        episodes = restarting.env_runner.sample()
        assert episodes and all(isinstance(e, MultiAgentEpisode) for e in episodes)
        # Whole episodes (an evaluation-style call) go through RLlib's loop too; batched sampling then starts afresh.
        whole = bandit.env_runner.sample(num_episodes=3)
        assert len(whole) >= 3 and all(isinstance(e, MultiAgentEpisode) and e.is_done for e in whole)
        (rollout,) = bandit.env_runner.sample()
        assert isinstance(rollout, Rollout) and rollout.env_steps() == 256  # 4 partners x 64 env steps each
    finally:
        restarting.stop()
        bandit.stop()


@pytest.mark.slow
def test_rollout_counts_what_was_played(ray_session) -> None:
    algo = _algorithm(True, seeds=(0,))
    try:
        (rollout,) = algo.env_runner.sample()
        # 4 partners x 64 env steps per partner, one one-step game per env step, both seats moving.
        assert rollout.env_steps() == 256 and rollout.agent_steps() == 512
        # Every ego head got its share of the games (round robin) and one row per game.
        counts = {mid: len(rows.actions) for mid, rows in rollout.modules.items()}
        assert counts == {mid: 64 for mid in algo.learner_group._learner.module.head_ids()}
        assert all(rows.lengths == [1] * 64 and all(rows.terminated) for rows in rollout.modules.values())
        assert np.isfinite(np.concatenate([np.asarray(r.logp) for r in rollout.modules.values()])).all()
    finally:
        algo.stop()


def test_the_removed_batched_sampling_key_still_loads_and_changes_nothing() -> None:
    # Trial folders trained before the key was removed hold it in their config.yaml.
    with pytest.warns(FutureWarning, match="run.batched_sampling is ignored"):
        exp = ExperimentConfig(population="bandit-s2-hand", seed=1, run={"batched_sampling": False})
    assert "batched_sampling" not in exp.model_dump()["run"]
    assert build_ppo_config([Replica(resolve(exp))]).env_runner_cls is BatchedEnvRunner
