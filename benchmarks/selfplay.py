"""Self-play speed: env steps to the score gate and env steps per second, per game, vs RLlib's default PPO.

For each game, in one run:
- `ours`: `tune_configs/selfplay_<game>.yaml` (tuned PPO), `--pairs` pairs through the real
  pipeline (`train_population`); steps to gate per pair, and env steps/s per trial;
- `rllib_default`: `PPOConfig()` defaults with RLlib's action-masking module per seat (shared
  for Hanabi), trained for `--default-seconds`; its steps/s, and its greedy self-play score
  at the end (1000 episodes) against the same gate.
Writes `benchmarks/results/selfplay_<games>.json`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.selfplay --games bandit blocks hanabi
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import ray
import torch
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.examples.rl_modules.classes.action_masking_rlm import (
    ActionMaskingTorchRLModule,
)

from benchmarks._common import write_result
from rllib_conv import envs
from rllib_conv.common import config_files
from rllib_conv.common.resources import config_file
from rllib_conv.envs.rllib_adapter import RLlibGame, game_env_config
from rllib_conv.partners.episodes import play_episodes
from rllib_conv.partners.trained import PolicyPartner
from rllib_conv.pipelines.selfplay import SeatMapping, seat_module_id, train_population
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

ROOT = Path(__file__).resolve().parents[1]


def ours(game: str, pairs: int, budget: int | None) -> dict:
    """Train `pairs` pairs with the tuned config; return steps to gate and speed."""
    overrides = [f"train_pairs={pairs}", "test_pairs=0", f"name=bench-{game}"] + ([f"run.timesteps={budget}"] if budget else [])
    raw = config_files.load_checked(config_file(f"selfplay_{game}.yaml"), overrides, schema=SelfPlayConfig)
    with tempfile.TemporaryDirectory() as tmp:
        _, report = train_population(raw, out=Path(tmp) / "pops", storage=Path(tmp) / "runs")
    steps = report["steps_to_gate"].dropna().tolist()
    return {
        "pairs": pairs,
        "passed": int(report["passed"].sum()),
        "steps_to_gate": steps,
        "median_steps_to_gate": float(np.median(steps)) if steps else None,
        "scores": report["score"].tolist(),
        "steps_per_s_per_trial": float(report["env_steps"].sum() / report["wall_s"].sum()),
    }


def rllib_default(game: str, cfg: SelfPlayConfig, seconds: float) -> dict:
    """RLlib's default PPO self-play for `seconds`; return its speed and final greedy score."""
    spec = RLModuleSpec(module_class=ActionMaskingTorchRLModule)
    agents = envs.make(game, **cfg.env_config).possible_agents
    ids = sorted({seat_module_id(cfg, a) for a in agents})
    algo = (
        PPOConfig()
        .environment(RLlibGame, env_config=game_env_config(game, cfg.env_config), disable_env_checking=True)
        .multi_agent(policies=set(ids), policy_mapping_fn=SeatMapping(cfg.shared_seats))
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={i: spec for i in ids}))
        .env_runners(sample_timeout_s=3600)  # one default iteration can exceed the 60 s default here
        .debugging(seed=0)
        .build_algo()
    )
    try:
        start, steps = time.perf_counter(), 0
        while time.perf_counter() - start < seconds:
            steps = algo.train()["env_runners"]["num_env_steps_sampled_lifetime"]
        elapsed = time.perf_counter() - start
        module = algo.get_module  # greedy play through the module's own masked forward pass
        seats = {}
        for i, a in enumerate(agents):
            m = module(seat_module_id(cfg, a))

            def logits(obs, mask, m=m):
                return m.forward_inference({"obs": {"observations": obs, "action_mask": mask}})["action_dist_inputs"]

            seats[a] = PolicyPartner(a, logits, greedy=True, seed=i)
        with torch.no_grad():
            score = float(play_episodes(envs.make(game, **cfg.env_config), seats, 1000, 0).mean())
        return {
            "env_steps": int(steps),
            "seconds": elapsed,
            "steps_per_s": steps / elapsed,
            "final_score": score,
            "passed": score >= cfg.gate.score,
        }
    finally:
        algo.stop()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks", "hanabi"])
    parser.add_argument("--pairs", type=int, default=2, help="self-play pairs of ours per game (2 run at once on 2 cores)")
    parser.add_argument("--budget", type=int, default=None, help="override the per-pair step budget")
    parser.add_argument("--default-seconds", type=float, default=600.0, help="training time given to RLlib's default")
    args = parser.parse_args()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    rows = []
    for game in args.games:
        cfg = config_files.validate(
            config_files.load(config_file(f"selfplay_{game}.yaml"), schema=SelfPlayConfig), schema=SelfPlayConfig
        )[0]
        mine = ours(game, args.pairs, args.budget)
        default = rllib_default(game, cfg, args.default_seconds)
        rows.append({"game": game, "gate": cfg.gate.score, "ours": mine, "rllib_default": default})
        table = pd.DataFrame(
            [
                {
                    "game": r["game"],
                    "gate": r["gate"],
                    "ours passed": f"{r['ours']['passed']}/{r['ours']['pairs']}",
                    "ours median steps to gate": r["ours"]["median_steps_to_gate"],
                    "ours steps/s": r["ours"]["steps_per_s_per_trial"],
                    "default steps/s": r["rllib_default"]["steps_per_s"],
                    "default steps": r["rllib_default"]["env_steps"],
                    "default score": r["rllib_default"]["final_score"],
                    "speed ratio": r["ours"]["steps_per_s_per_trial"] / r["rllib_default"]["steps_per_s"],
                }
                for r in rows
            ]
        )
        print(table.to_string(index=False, float_format="{:.2f}".format), flush=True)
        # After every game, so an interrupted run keeps the games it finished; one file per
        # set of games, so a run on some games keeps the results of the others.
        path = write_result(
            "selfplay_" + "_".join(args.games), {"rows": rows, "pairs": args.pairs, "default_seconds": args.default_seconds}
        )
        print(f"wrote {path}")
    ray.shutdown()


if __name__ == "__main__":
    main()
