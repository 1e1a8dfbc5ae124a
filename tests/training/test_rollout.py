"""The batched sampler's bookkeeping and train batch equal RLlib's episodes and learner connector on the same moves.

Hand-built multi-step episodes (the bandit never has them) go step by step into RLlib's
`MultiAgentEpisode` and into the batched runner's `RunningEpisode`: a game that ends
(terminated), one the env truncates, one the sample cut while it was still running, and
an agent that left a running episode early. RLlib's learner connector makes its train
batch from the episodes, `rollout_train_batch` from the `Rollout` the running episodes
wrote; GAE, value targets, standardization and the dropped bootstrap rows must come out
the same, row for row.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.learner.training_data import TrainingData
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.evaluation.postprocessing import Postprocessing

from rllib_conv.learners.packed.rollout import ModuleRows, Rollout, rollout_train_batch
from rllib_conv.modules.multi import replica_id
from rllib_conv.training.batched_env_runner import RunningEpisode
from tests.helpers import bandit_setup, build_learner

COLUMNS = (Columns.ACTIONS, Columns.ACTION_LOGP, Postprocessing.ADVANTAGES, Postprocessing.VALUE_TARGETS)


def _obs(rng: np.random.Generator) -> dict[str, np.ndarray]:
    return {"observations": np.eye(4, dtype=np.float32)[rng.integers(4)], "action_mask": np.ones(8, dtype=np.float32)}


def _episode(rng, learner, steps: int, ends: str, early_agent: bool, rollout: Rollout) -> MultiAgentEpisode:
    """Play one episode of two ego agents (replica 0's heads for partners 0 and 1) into RLlib's episode and into `rollout`.

    `ends`: "terminated", "truncated" (by the env) or "open" (still running when the sample ended).
    `early_agent`: the second agent's game ends one step before the episode does.
    """
    heads = learner.module.head_ids()
    mapping = {"a": heads[0], "b": heads[1]}
    space, actions_space = learner.module[heads[0]].observation_space, learner.module[heads[0]].action_space
    episode = MultiAgentEpisode(
        observation_space={a: space for a in mapping},
        action_space={a: actions_space for a in mapping},
        agent_to_module_mapping_fn=lambda aid, eps: mapping[aid],
    )
    obs = {a: _obs(rng) for a in mapping}
    episode.add_env_reset(observations=obs)
    ours = RunningEpisode(obs, lambda aid, eps: mapping[aid])
    live = set(mapping)
    for t in range(steps):
        last = t == steps - 1
        acting = sorted(live)
        actions = {a: np.int64(rng.integers(8)) for a in acting}
        logp = {a: np.float32(-rng.uniform(0.5, 3.0)) for a in acting}
        rewards = {a: float(rng.normal()) for a in acting}
        obs = {a: _obs(rng) for a in acting}
        terms = {a: False for a in acting}
        truncs = {a: False for a in acting}
        if early_agent and t == steps - 2:
            terms["b"] = True
            live.discard("b")
        if last and ends == "terminated":
            terms = {a: True for a in acting}
        if last and ends == "truncated":
            truncs = {a: True for a in acting}
        terms["__all__"] = last and ends == "terminated"
        truncs["__all__"] = last and ends == "truncated"
        episode.add_env_step(
            observations=obs,
            actions=actions,
            rewards=rewards,
            terminateds=terms,
            truncateds=truncs,
            extra_model_outputs={a: {Columns.ACTION_LOGP: logp[a]} for a in acting},
        )
        ours.record(actions, logp, obs, rewards, terms, truncs)
        assert ours.is_done == episode.is_done
    ours.emit(rollout, set(mapping.values()))
    rollout.num_env_steps += steps
    return episode


@pytest.mark.parametrize("seed", [0, 1])
def test_rollout_batch_equals_the_learner_connectors(seed: int) -> None:
    rng = np.random.default_rng(seed)
    learner = build_learner(bandit_setup(lam=0.5))
    plans = [(3, "terminated", False), (4, "open", True), (2, "truncated", False), (1, "terminated", False), (5, "open", False)]
    rollout = Rollout()
    episodes = [_episode(rng, learner, steps, ends, early, rollout) for steps, ends, early in plans]
    theirs = learner._make_batch_if_necessary(TrainingData(episodes=episodes))
    ours = rollout_train_batch([rollout], learner.module, learner.config.gamma, learner.config.lambda_)
    heads = set(learner.module.head_ids()[:2])
    assert set(ours.policy_batches) == heads == set(theirs.policy_batches) & heads
    for mid in heads:
        mine, rllib = ours.policy_batches[mid], theirs.policy_batches[mid]
        assert len(mine) == len(rllib) == len(rollout.modules[mid].actions)
        for key in ("observations", "action_mask"):
            torch.testing.assert_close(
                torch.as_tensor(mine[Columns.OBS][key]), torch.as_tensor(rllib[Columns.OBS][key]), rtol=0, atol=0
            )
        for col in COLUMNS:
            torch.testing.assert_close(
                torch.as_tensor(mine[col]), torch.as_tensor(rllib[col]), rtol=0, atol=0, check_dtype=False, msg=f"{mid} {col}"
            )
    assert ours.env_steps() == sum(steps for steps, _, _ in plans)
    # Standardized over real and bootstrap rows together: the real rows alone are near, not at, unit spread.
    advantages = np.asarray(ours.policy_batches[replica_id("ego@hand-train-0", 0)][Postprocessing.ADVANTAGES])
    assert advantages.std() == pytest.approx(1.0, abs=0.3)


def test_a_segment_needs_moves_and_one_more_observation() -> None:
    obs = {"observations": np.zeros(4, dtype=np.float32), "action_mask": np.ones(8, dtype=np.float32)}
    with pytest.raises(ValueError, match="n >= 1 moves and n \\+ 1 observations"):
        ModuleRows().add([obs, obs], [1, 2], [0.0, 0.0], [1.0, 1.0], True, False)
    with pytest.raises(ValueError, match="n >= 1 moves"):
        ModuleRows().add([obs], [], [], [], True, False)


def test_a_batch_mixing_rollouts_and_episodes_is_refused() -> None:
    learner = build_learner(bandit_setup())
    episode = _episode(np.random.default_rng(0), learner, 1, "terminated", False, Rollout())
    with pytest.raises(TypeError, match="mixes Rollouts and RLlib episodes"):
        learner._make_batch_if_necessary(TrainingData(episodes=[Rollout(), episode]))
