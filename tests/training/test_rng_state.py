"""`rng_state`: save, draw, restore, draw again -> the same random draws from every generator it keeps.

The fast tests hold the real generators (the games of a `ReplicatedGame`, a weighted
partner schedule, the learner's per-module permuters, the replicas' exploration
generators, the process's torch/numpy/random) in a stand-in for the algorithm's runner
and learner groups; the slow one resumes a real RLlib algorithm from its checkpoint.
"""

from __future__ import annotations

import itertools
import random
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Callable

import numpy as np
import pytest
import torch

from rllib_conv.envs.replicated_game import ReplicatedGame, replicated_env_config
from rllib_conv.learners.packed.minibatches import ModulePermuters
from rllib_conv.modules.mapping import PartnerMapping
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.modules.partner_schedule import WeightedPartners
from rllib_conv.training import rng_state
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.weights import learner_module
from tests.helpers import bandit_setup

PARTNERS = ["p0", "p1", "p2"]
MODULES = ["ego@p0#0", "ego@p1#0"]
EPISODES = itertools.count()


def runner(seed: int) -> SimpleNamespace:
    """An env runner's RNG-carrying parts, real ones: two bandit copies, a weighted partner mapping, two samplers."""
    env = ReplicatedGame(replicated_env_config("bandit", {}, [seed, seed + 1], seed))
    env.reset(seed=seed)
    mapping = PartnerMapping(PARTNERS, "player_0", "player_1", schedule=WeightedPartners(dict.fromkeys(PARTNERS, 1.0), [seed]))
    samplers = SimpleNamespace(samplers=[torch.Generator().manual_seed(seed + 10), torch.Generator().manual_seed(seed + 11)])
    return SimpleNamespace(
        config=SimpleNamespace(policy_mapping_fn=mapping),
        env=SimpleNamespace(envs=[SimpleNamespace(unwrapped=env)]),
        module={STACK_ID: samplers},
    )


class Result:
    """One remote call's answer, as RLlib's `foreach_*` returns them."""

    def __init__(self, value: Any, actor_id: int = 0) -> None:
        self.value, self.actor_id = value, actor_id

    def get(self) -> Any:
        return self.value


class RunnerGroup:
    """The local runner and remote ones by actor ID, with `EnvRunnerGroup`'s calls `rng_state` makes."""

    def __init__(self, local: SimpleNamespace, remote: dict[int, SimpleNamespace]) -> None:
        self.local_env_runner, self.remote = local, remote

    def num_remote_env_runners(self) -> int:
        return len(self.remote)

    def foreach_env_runner(
        self,
        fn: Callable,
        local_env_runner: bool = True,
        remote_worker_ids: list[int] | None = None,
        return_actor_ids: bool = False,
    ) -> list:
        assert not local_env_runner
        return [Result(fn(r), i) for i, r in self.remote.items() if remote_worker_ids is None or i in remote_worker_ids]


class LearnerGroup:
    is_local = True

    def __init__(self, learner: SimpleNamespace) -> None:
        self.learner = learner

    def foreach_learner(self, fn: Callable) -> list[Result]:
        return [Result(fn(self.learner))]


def algorithm(seed: int = 0) -> SimpleNamespace:
    permuters = ModulePermuters({mid: seed + i for i, mid in enumerate(MODULES)})
    return SimpleNamespace(
        env_runner_group=RunnerGroup(runner(seed), {1: runner(seed + 100)}),
        learner_group=LearnerGroup(SimpleNamespace(permuters=permuters)),
    )


def draws(algo: SimpleNamespace, episodes: int = 4) -> dict[str, Any]:
    """One draw from every generator `rng_state` keeps, in a fixed order."""
    group = algo.env_runner_group
    out: dict[str, Any] = {
        "torch": torch.rand(3).tolist(),
        "numpy": np.random.rand(3).tolist(),
        "random": [random.random() for _ in range(3)],
    }
    for name, r in (("local", group.local_env_runner), ("remote", group.remote[1])):
        game = r.env.envs[0].unwrapped
        out[f"{name}/games"] = [repr(game.reset()[0]) for _ in range(episodes)]
        # New episode IDs every call: each episode's partner is drawn once, on first sight.
        out[f"{name}/partners"] = [
            r.config.policy_mapping_fn("player_0", SimpleNamespace(id_=f"episode-{next(EPISODES)}")) for _ in range(episodes)
        ]
        out[f"{name}/samplers"] = [torch.rand(2, generator=g).tolist() for g in r.module[STACK_ID].samplers]
    out["permuters"] = [algo.learner_group.learner.permuters(mid, 8).tolist() for mid in MODULES]
    return out


@pytest.fixture(autouse=True)
def _keep_the_process_generators():
    """This test reseeds the process's generators; give the next test back the state it had."""
    state = (torch.get_rng_state(), np.random.get_state(), random.getstate())
    yield
    torch.set_rng_state(state[0])
    np.random.set_state(state[1])
    random.setstate(state[2])


def test_restore_reproduces_every_draw_after_the_save(tmp_path: Path) -> None:
    algo = algorithm()
    torch.manual_seed(1)
    np.random.seed(1)
    random.seed(1)
    draws(algo)  # some history before the checkpoint
    rng_state.save(algo, tmp_path)
    assert (tmp_path / rng_state.RNG_FILE).is_file()
    first = draws(algo)
    rng_state.load(algo, tmp_path)
    again = draws(algo)
    assert again == first
    # Without a restore the same calls draw something else, so the equality above is not a given.
    assert draws(algo) != first


@pytest.mark.parametrize(
    "part",
    [
        "torch",
        "numpy",
        "random",
        "local/games",
        "local/partners",
        "local/samplers",
        "remote/games",
        "remote/partners",
        "remote/samplers",
        "permuters",
    ],
)
def test_each_generator_repeats_its_draws(part: str) -> None:
    algo = algorithm()
    state = rng_state.capture(algo)
    first = draws(algo)
    rng_state.restore(algo, state)
    assert draws(algo)[part] == first[part]
    assert draws(algo)[part] != first[part], f"{part}: draws repeat without a restore; the test would prove nothing"


def test_a_fresh_algorithm_restored_draws_as_the_saved_one(tmp_path: Path) -> None:
    # What a resumed trial does: new objects in a process whose generators drew something else, then `load`.
    saved = algorithm(seed=3)
    draws(saved)
    rng_state.save(saved, tmp_path)
    first = draws(saved)
    resumed = algorithm(seed=3)
    torch.manual_seed(99)
    np.random.seed(99)
    rng_state.load(resumed, tmp_path)
    assert draws(resumed) == first


def test_load_without_a_saved_state_changes_nothing(tmp_path: Path) -> None:
    algo = algorithm()
    before = rng_state.capture(algo)
    rng_state.load(algo, tmp_path)  # a checkpoint from before RNG states were saved
    after = rng_state.capture(algo)
    assert repr(after) == repr(before)


@pytest.mark.slow
def test_a_real_algorithm_resumed_with_its_rng_state_trains_the_next_iteration_as_the_uninterrupted_one(
    ray_session, tmp_path: Path
) -> None:
    # As `AlgorithmTrainable` resumes: a new algorithm, the weights from RLlib's checkpoint, then the RNG state saved beside it.
    config = build_ppo_config(bandit_setup(model={"hidden": 8}, ppo={"rollout_per_partner": 16, "num_epochs": 2}))
    algo = config.build_algo()
    try:
        algo.train()  # some history before the checkpoint
        algo.save_to_path(tmp_path / "checkpoint")
        rng_state.save(algo, tmp_path / "checkpoint")
        uninterrupted = outcome(algo)
    finally:
        algo.stop()
    resumed, weights_only = config.build_algo(), config.build_algo()
    try:
        resumed.restore_from_path(tmp_path / "checkpoint")
        rng_state.load(resumed, tmp_path / "checkpoint")
        weights_only.restore_from_path(tmp_path / "checkpoint")
        assert same(outcome(resumed), uninterrupted)
        assert not same(outcome(weights_only), uninterrupted)  # the RNG state is what makes them equal
    finally:
        resumed.stop()
        weights_only.stop()


def outcome(algo: Any) -> dict[str, torch.Tensor]:
    """One more training iteration's weights: what it sampled (games, partners, exploration) and how it shuffled decide them."""
    algo.train()
    return {k: v.detach().clone() for k, v in learner_module(algo)[STACK_ID].state_dict().items()}


def same(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
