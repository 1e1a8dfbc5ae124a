"""An env that raises once: a crashed remote env runner is restarted and training goes on;
with `restart_failed_sub_environments` the local runner recreates the env instead of failing."""

from __future__ import annotations

from pathlib import Path

import pytest

from rllib_conv import envs, partners
from rllib_conv.envs.bandit import CollaborativeBanditEnv
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.ego_setup import setup_for
from rllib_conv.training.experiment import ExperimentConfig

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)


def _flaky_factory(marker: Path, crash_at: int):
    """A bandit whose `crash_at`-th step raises, once per `marker` file (which it then creates)."""

    class FlakyBandit(CollaborativeBanditEnv):
        steps = 0

        def step(self, actions):
            FlakyBandit.steps += 1
            if FlakyBandit.steps >= crash_at and not marker.exists():
                marker.write_text("crashed")
                raise RuntimeError("flaky env: simulated crash")
            return super().step(actions)

    return FlakyBandit


def _algo(tmp_path: Path, **run):
    envs.register("flaky_bandit", _flaky_factory(tmp_path / "crashed", crash_at=100), overwrite=True)
    pop = partners.get("bandit-s1-hand").model_copy(update={"env": "flaky_bandit"})
    exp = ExperimentConfig(population="flaky", model={"hidden": 8}, ppo={"rollout_per_partner": 32, "num_epochs": 1}, run=run)
    config = build_ppo_config(setup_for(exp, pop, pop.entries("train")))
    # RLlib waits 60 s before restarting a failed runner by default; these tests check the restart, not the wait.
    return config.fault_tolerance(delay_between_env_runner_restarts_s=1.0).build_algo()


def _steps(result: dict) -> int | None:
    """Env steps sampled so far; None for an iteration in which no runner returned samples."""
    runners = result.get("env_runners")
    return int(runners["num_env_steps_sampled_lifetime"]) if runners else None


def test_a_crashed_env_runner_is_restarted_and_training_continues(ray_session, tmp_path) -> None:
    algo = _algo(tmp_path, num_env_runners=1)
    try:
        first = algo.env_runner_group.foreach_env_runner(lambda r: r.worker_index, local_env_runner=False)
        steps, crashed_at = [], None
        for _ in range(60):
            steps.append(_steps(algo.train()) or (steps[-1] if steps else 0))
            if crashed_at is None and (tmp_path / "crashed").exists():
                crashed_at = steps[-1]
            if crashed_at is not None and steps[-1] >= crashed_at + 256:
                break
        assert crashed_at is not None, "the env should have raised"
        assert steps[-1] >= crashed_at + 256, f"sampling did not resume after the crash: {steps}"
        assert algo.env_runner_group.num_healthy_remote_workers() == 1
        assert algo.env_runner_group.foreach_env_runner(lambda r: r.worker_index, local_env_runner=False) == first
    finally:
        algo.stop()


def test_the_local_runner_recreates_a_failed_env_when_asked(ray_session, tmp_path) -> None:
    algo = _algo(tmp_path, num_env_runners=0, restart_failed_sub_environments=True)
    try:
        steps = [_steps(algo.train()) for _ in range(6)]  # every iteration samples: the env is recreated in place
        assert (tmp_path / "crashed").exists()
        assert steps == sorted(steps) and steps[-1] >= 6 * 64 - 64, steps
    finally:
        algo.stop()
    (tmp_path / "strict").mkdir()
    algo = _algo(tmp_path / "strict", num_env_runners=0)  # default: the error surfaces, naming the env
    try:
        with pytest.raises(RuntimeError) as failure:
            for _ in range(6):
                algo.train()
        assert "simulated crash" in str(failure.value.__cause__)
    finally:
        algo.stop()
