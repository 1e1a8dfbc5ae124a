"""Ego-training throughput (env steps per second) vs RLlib's default multi-agent PPO, side by side.

For each game (bandit with 2 symmetric contexts, blocks), in one run:
- `ours`: the modular ego (lam 0.5) against 4 scripted partners with the paper's
  hyperparameters, vectorised sub-environments, one torch thread, one local env runner;
- `rllib_default`: `PPOConfig()` defaults (2 env runners, 1 env each, 256x256 MLPs,
  4000-step batches, minibatch 128, 30 epochs) with one learning module per seat
  (RLlib's `ActionMaskingTorchRLModule`, since the observations carry a mask), and
  `sample_timeout_s` raised from 60 s, which one default iteration exceeds here.
Both are timed over whole training iterations after one warm-up iteration, and the table
reports env steps per second and their ratio. Writes `benchmarks/results/train_throughput.json`.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_throughput.py [--seconds 60]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import pandas as pd
import ray
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.examples.rl_modules.classes.action_masking_rlm import (
    ActionMaskingTorchRLModule,
)

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import write_result  # noqa: E402

from rllib_conv import partners  # noqa: E402
from rllib_conv.envs.rllib_adapter import to_rllib  # noqa: E402
from rllib_conv.partners.blocks import (  # noqa: E402
    TEST_PERMUTATIONS,
    TRAIN_PERMUTATIONS,
    PermutationPartner,
)
from rllib_conv.training.algorithm import build_ppo_config  # noqa: E402
from rllib_conv.training.ego_setup import resolve  # noqa: E402
from rllib_conv.training.experiment import ExperimentConfig  # noqa: E402


def _blocks_four(tmp: Path) -> str:
    """A 4-partner blocks population (the 3 training permutations + 1 test one), as a manifest."""
    perms = TRAIN_PERMUTATIONS + TEST_PERMUTATIONS[:1]
    pop = partners.from_partners(
        "blocks-perm4", "blocks", {}, [PermutationPartner(f"perm-{''.join(map(str, p))}", list(p)) for p in perms], []
    )
    return str(pop.save(tmp / "blocks-perm4.json"))


def ours(population: str) -> PPOConfig:
    """The modular ego's config (paper hyperparameters) for `population`."""
    return build_ppo_config(resolve(ExperimentConfig(population=population, lam=0.5, seed=0)))


def rllib_default(env: str, env_config: dict) -> PPOConfig:
    """RLlib's default PPO, multi-agent: one default-sized module per seat.

    The module is RLlib's own action-masking PPO module (the default one cannot read
    Dict observations); everything else is `PPOConfig()`'s default.
    """
    spec = RLModuleSpec(module_class=ActionMaskingTorchRLModule)
    return (
        PPOConfig()
        .environment(to_rllib(env), env_config=env_config)
        .multi_agent(policies={"player_0", "player_1"}, policy_mapping_fn=lambda agent_id, episode, **kw: agent_id)
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={"player_0": spec, "player_1": spec}))
        # The default 60 s sample timeout is shorter than one default iteration takes here.
        .env_runners(sample_timeout_s=3600)
        .debugging(seed=0)
    )


def steps_per_second(config: PPOConfig, seconds: float) -> tuple[float, int]:
    """Train for at least `seconds` (whole iterations, after a warm-up one); return (steps/s, iterations)."""
    algo = config.build_algo()
    try:
        algo.train()
        start, steps, iters = time.perf_counter(), 0, 0
        while time.perf_counter() - start < seconds or iters < 1:
            result = algo.train()
            steps += result["env_runners"]["num_env_steps_sampled"]
            iters += 1
        return steps / (time.perf_counter() - start), iters
    finally:
        algo.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="minimum timed training per measurement")
    args = parser.parse_args()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    tmp = Path(__file__).resolve().parent / "results"
    games = {"bandit": ("bandit-s2-hand", {"symmetric": 2}), "blocks": (_blocks_four(tmp), {})}
    rows = []
    try:
        for game, (population, env_config) in games.items():
            mine, n_mine = steps_per_second(ours(population), args.seconds)
            default, n_default = steps_per_second(rllib_default(game, env_config), args.seconds)
            rows.append(
                {"env": game, "ours_steps_per_s": mine, "ours_iters": n_mine, "default_steps_per_s": default, "default_iters": n_default, "ratio": mine / default}
            )
            print(pd.DataFrame(rows).to_string(index=False, float_format="{:.1f}".format), flush=True)
    finally:
        (tmp / "blocks-perm4.json").unlink(missing_ok=True)
        ray.shutdown()
    path = write_result("train_throughput", {"seconds": args.seconds, "rows": rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
