"""Ego-training throughput (env steps per second) beside RLlib's default multi-agent PPO and the game's own ceiling.

For each game (bandit with 2 symmetric contexts, blocks, Hanabi; Overcooked's cramped_room
against its convention cooks on request), in one run:
- `ours_1`: the modular ego (lam 0.5) with the paper's hyperparameters against 4 scripted
  partners (Hanabi: its scripted population), one seed: what one trial of a lone seed gets;
- `ours_3`: three seeds packed as replicas of one algorithm (how `train` runs an
  experiment's seeds), counted in the moves of all three replicas' own game copies, as
  training budgets count them (each replica trains as alone);
- `ours_3_episodes`: the same through RLlib's episode objects (`LeanEnvRunner`, the reference),
  how every ego sampled before `BatchedEnvRunner` (same batches, same weights);
- `ours_10` (bandit only): ten seeds packed, as a 10-seed experiment's trial holds them
  when nothing else runs beside it;
- `rllib_default`: `PPOConfig()` defaults (2 env runners, 1 env each, 256x256 MLPs,
  4000-step batches, minibatch 128, 30 epochs) with one learning module per seat
  (RLlib's `ActionMaskingTorchRLModule`, since the observations carry a mask),
  `sample_timeout_s` raised from 60 s, which one default iteration exceeds here, and
  RLlib's env check off (it plays a random move that ignores the mask);
- `env_ceiling`: random legal moves through our RLlib adapter, in env steps (a bandit env
  step is both players' moves), as `env_throughput.py` measures them;
- `target`: issue 22's per-trial target.
Timed over whole training iterations after one warm-up iteration. Writes
`benchmarks/results/train_throughput.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.train_throughput [--seconds 30] [--games bandit blocks hanabi]
    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.train_throughput --games overcooked --name train_throughput_overcooked
"""

from __future__ import annotations

import argparse
import functools
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd
import ray
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.learner.training_data import TrainingData
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.examples.rl_modules.classes.action_masking_rlm import (
    ActionMaskingTorchRLModule,
)

from benchmarks._common import write_result
from benchmarks.env_throughput import adapter_steps_per_second
from rllib_conv import partners
from rllib_conv.envs.rllib_adapter import to_rllib
from rllib_conv.partners.blocks import (
    TEST_PERMUTATIONS,
    TRAIN_PERMUTATIONS,
    PermutationPartner,
)
from rllib_conv.training.algorithm import Replica, build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.lean_env_runner import LeanEnvRunner
from rllib_conv.training.replica_steps import replica_env_steps


def _blocks_four(tmp: Path) -> str:
    """A 4-partner blocks population (the 3 training permutations + 1 test one), as a manifest."""
    perms = TRAIN_PERMUTATIONS + TEST_PERMUTATIONS[:1]
    pop = partners.from_partners(
        "blocks-perm4", "blocks", {}, [PermutationPartner(f"perm-{''.join(map(str, p))}", list(p)) for p in perms], []
    )
    return str(pop.save(tmp / "blocks-perm4.json"))


def ours(population: str, seeds: int, batched: bool = True, method: str = "modular") -> PPOConfig:
    """The ego's config (paper hyperparameters; `method`, the modular ego with lam 0.5 by default) for `population`, `seeds` seeds packed as replicas."""
    lam = {"lam": 0.5} if method == "modular" else {}
    config = build_ppo_config(
        [Replica(resolve(ExperimentConfig(population=population, method=method, seed=s, **lam))) for s in range(seeds)]
    )
    return config if batched else config.env_runners(env_runner_cls=LeanEnvRunner)


def rllib_default(env: str, env_config: dict) -> PPOConfig:
    """RLlib's default PPO, multi-agent: one default-sized module per seat.

    The module is RLlib's own action-masking PPO module (the default one cannot read
    Dict observations); everything else is `PPOConfig()`'s default.
    """
    spec = RLModuleSpec(module_class=ActionMaskingTorchRLModule)
    return (
        PPOConfig()
        # RLlib's env check steps each env once with a random action that ignores the mask, which our
        # Hanabi refuses when it picks an illegal move (random, so only now and then): checked off.
        .environment(to_rllib(env), env_config=env_config, disable_env_checking=True)
        .multi_agent(policies={"player_0", "player_1"}, policy_mapping_fn=lambda agent_id, episode, **kw: agent_id)
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={"player_0": spec, "player_1": spec}))
        # The default 60 s sample timeout is shorter than one default iteration takes here.
        .env_runners(sample_timeout_s=3600)
        .debugging(seed=0)
    )


def steps_per_second(config: PPOConfig, seconds: float, replicas: int | None = None) -> tuple[float, int]:
    """Train for at least `seconds` (whole iterations, after a warm-up one); return (env steps/s, iterations).

    With `replicas`, the env steps are the moves every replica's own game copies made
    (`replica_env_steps`, what training budgets count); without, RLlib's env steps.
    """

    def played(result: dict) -> int:
        if replicas is None:
            return result["env_runners"]["num_env_steps_sampled_lifetime"]
        return sum(replica_env_steps(result, r) for r in range(replicas))

    algo = config.build_algo()
    try:
        before = played(algo.train())
        start, iters = time.perf_counter(), 0
        while time.perf_counter() - start < seconds or iters < 1:
            result = algo.train()
            iters += 1
        return (played(result) - before) / (time.perf_counter() - start), iters
    finally:
        algo.stop()


TARGETS = {"bandit": 3000, "blocks": 8000, "hanabi": 2500, "overcooked": None}  # issue 22, env steps/s per trial
# Issue 48: Overcooked's target is a ratio, ours_1 >= 10x RLlib's default config on the same env.
RATIO_TARGETS = {"overcooked": 10.0}
# What RLlib's default and the ceiling play.
ENV_CONFIGS = {"bandit": {"symmetric": 2}, "blocks": {}, "hanabi": {}, "overcooked": {"layout": "cramped_room"}}


def fixed_update(algo: Any, episodes: Any) -> Callable[[], Any]:
    """One learner update of `algo` (built from `ours`) on the sampled `episodes`, as `train()` runs it, to call again and again on the same batch."""
    config = algo.config
    return functools.partial(
        algo.learner_group._learner.update,
        training_data=TrainingData(episodes=episodes),
        num_epochs=config.num_epochs,
        minibatch_size=config.minibatch_size,
        shuffle_batch_per_epoch=True,
        timesteps={},
    )


def population_of(game: str, folder: Path) -> str:
    """The partner population `ours` trains `game`'s ego against (blocks: a 4-partner manifest written to `folder`)."""
    builtin = {"bandit": "bandit-s2-hand", "hanabi": "hanabi-scripted", "overcooked": "overcooked-cramped_room-cooks"}
    return builtin.get(game) or _blocks_four(folder)


MOVES_PER_STEP = {"bandit": 2, "blocks": 1, "hanabi": 1, "overcooked": 2}  # agent moves in one env step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="minimum timed training per measurement")
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks", "hanabi"], choices=list(TARGETS))
    parser.add_argument("--name", default="train_throughput", help="the result file's name (benchmarks/results/NAME.json)")
    args = parser.parse_args()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    tmp = Path(__file__).resolve().parent / "results"
    rows = []
    try:
        for game in args.games:
            population, env_config = population_of(game, tmp), ENV_CONFIGS[game]
            one, n_one = steps_per_second(ours(population, 1), args.seconds, replicas=1)
            three, n_three = steps_per_second(ours(population, 3), args.seconds, replicas=3)
            episodes, n_episodes = steps_per_second(ours(population, 3, batched=False), args.seconds, replicas=3)
            ten, n_ten = steps_per_second(ours(population, 10), args.seconds, replicas=10) if game == "bandit" else (None, 0)
            default, n_default = steps_per_second(rllib_default(game, env_config), args.seconds)
            ceiling = adapter_steps_per_second(game, env_config, 20_000) / MOVES_PER_STEP[game]
            rows.append(
                {
                    "env": game,
                    "ours_1": one,
                    "ours_3": three,
                    "ours_3_episodes": episodes,
                    "ours_10": ten,
                    "rllib_default": default,
                    "env_ceiling": ceiling,
                    "target": TARGETS[game],
                    "ratio_target": RATIO_TARGETS.get(game),
                    "ours_1/default": one / default,
                    "ours_3/default": three / default,
                    "ours_3/ours_3_episodes": three / episodes,
                    "ours_3/ceiling": three / ceiling,
                    "iterations": {
                        "ours_1": n_one,
                        "ours_3": n_three,
                        "ours_3_episodes": n_episodes,
                        "ours_10": n_ten,
                        "rllib_default": n_default,
                    },
                }
            )
            print(pd.DataFrame(rows).drop(columns="iterations").to_string(index=False, float_format="{:.2f}".format), flush=True)
    finally:
        (tmp / "blocks-perm4.json").unlink(missing_ok=True)
        ray.shutdown()
    path = write_result(args.name, {"seconds": args.seconds, "rows": rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
