"""How far ego training is from the machine's arithmetic: FLOPs per env step, the speed they run at, each plan's floor.

For each game, `ours` with 3 seeds packed as `train` packs them (paper hyperparameters;
Hanabi against its scripted partners, whose moves need no network): one iteration's
sampling and its learner update are counted with torch's `FlopCounterMode` (matrix
products, forward and backward) and timed (medians over `--repeats`, alternating, on one
fixed batch for the update). Beside them, the machine's own speed at the same arithmetic:
one core's float32 batched matrix product at the learner's largest layer (`peak`: the
replicas x minibatch rows x hidden units of its hidden-to-hidden layers), the best the
update could run at, and the same product in bfloat16 (`peak_bf16`: the opt-in
`ppo.precision: bfloat16` learner's matrix products; several times float32's on a CPU with
AMX or AVX512-BF16 units, slower without).

The floor of a plan's ego training counts every ego the full plan trains as it trains it
(`plan_flops`): each population with its own partner count (so its own number of heads), each
method with its own arithmetic (every head on every row where the loss reads them all, one
head for BaselineAgg and MAML, `z_dim`, the population's budget and rollout overrides), 3 seeds
packed per trial. A self-play population does not exist before its stage runs; it is stood in
for by as many random partners as its entry trains pairs (the ego's arithmetic depends on the
partner count, not on the partners). The floor is the plan's FLOPs / (cores x peak): what no
change to the training loop beats without changing the networks, the epochs or the budgets. It
leaves out the partners' networks (self-play partners act through networks as large as the
ego's task module), self-play, adaptation and evaluation: a lower bound of the train stage, and
of the plan; `plan_train_floor_bf16_min` is the same at the bfloat16 peak. With `--run` (one
game's `reproduce` folder past its self-play stage) it also counts self-play as that run
trained it (each pair's env steps x a pair's FLOPs per env step) and the adapt stage on its
populations (every curve's budget x its ego's FLOPs per env step, the new partner its only
one, lam 0); `plan_floor_min` is then the whole plan's floor but evaluation, written to
`flop_floor_<game>_run.json`. The machine (CPU
model, vector ISA) is in the result, as every benchmark's. Writes
`benchmarks/results/flop_floor.json`, and per game the plan's rows under `plans`.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.flop_floor [--repeats 5] [--games bandit blocks hanabi] [--seeds 3] [--run DIR]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

import pandas as pd
import ray
import torch
from ray.rllib.utils.metrics import ENV_RUNNER_RESULTS, NUM_ENV_STEPS_SAMPLED_LIFETIME
from torch.utils.flop_counter import FlopCounterMode

from benchmarks._common import median_seconds, write_result
from benchmarks.train_throughput import fixed_update, ours, population_of
from rllib_conv import envs, partners
from rllib_conv.common import config_files
from rllib_conv.common.resources import config_file
from rllib_conv.common.run_folders import POPULATIONS_DIR
from rllib_conv.partners.hanabi import RandomLegalPartner
from rllib_conv.pipelines.plans import plan_for
from rllib_conv.pipelines.reproduce import ARGUMENTS, Reproduction, _merge
from rllib_conv.pipelines.selfplay import build_selfplay_config
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.training.algorithm import Replica, build_ppo_config, packing_key
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.replica_steps import replica_env_steps

SEEDS = 3  # replicas per trial, as `train` packs a 3-seed experiment
TARGET_MINUTES = {"bandit": 15, "blocks": 60, "hanabi": 45}  # issue 49: the whole plan's wall time (EPYC)


def flops(call: Any) -> tuple[int, Any]:
    """(FLOPs of the matrix products `call()` runs, forward and backward; its return value)."""
    counter = FlopCounterMode(display=False)
    with counter:
        out = call()
    return counter.get_total_flops(), out


def peak_gflops(rows: int, hidden: int, repeats: int = 20, dtype: torch.dtype = torch.float32) -> float:
    """One core's GFLOP/s on `SEEDS` stacked [rows, hidden] x [hidden, hidden] products (the learner's largest layer) in `dtype`."""
    a, b = torch.randn(SEEDS, rows, hidden, dtype=dtype), torch.randn(SEEDS, hidden, hidden, dtype=dtype)
    seconds = median_seconds({"bmm": lambda: torch.bmm(a, b)}, repeats)["bmm"]
    return 2 * SEEDS * rows * hidden * hidden / seconds / 1e9


def iteration_flops(algo: Any) -> tuple[int, int, int, Any]:
    """(sampling FLOPs, update FLOPs, env steps) of one iteration of `algo` after a warm-up one, and that iteration's episodes."""
    before = algo.train()  # warm-up: optimizer states exist, the env runner's weights are set
    after = algo.train()
    steps = sum(replica_env_steps(after, r) - replica_env_steps(before, r) for r in range(SEEDS))
    sample_flops, episodes = flops(algo.env_runner.sample)
    update_flops, _ = flops(fixed_update(algo, episodes))
    return sample_flops, update_flops, steps, episodes


def _stand_in(game: str, entry: dict[str, Any], folder: Path) -> str:
    """A population of as many random partners as self-play `entry` trains pairs, in its game and seat (a manifest path)."""
    config = config_files.read_yaml(config_file(f"selfplay_{game}.yaml"), "self-play config")
    merged = {**config, **{k: v for k, v in entry.items() if k != "populations"}}
    pop = partners.from_partners(
        f"stand-in-{entry['name']}",
        game,
        merged.get("env_config", {}),
        [RandomLegalPartner(f"sp{k:02d}", seed=k) for k in range(int(merged.get("train_pairs", 10)))],
        [],
        partner_agent=merged.get("partner_agent", "player_1"),
    )
    return str(pop.save(folder / f"stand-in-{entry['name']}.json"))


def ego_flops_per_step(settings: dict[str, Any], cache: dict[Any, float]) -> tuple[float, Any]:
    """FLOPs per env step of an experiment's egos (`settings` without seed), `SEEDS` packed; cached by packing key.

    Returns them and the first seed's `EgoSetup`."""
    exps = [resolve(ExperimentConfig.model_validate({**settings, "seed": s})) for s in range(SEEDS)]
    key = packing_key(exps[0])
    if key not in cache:
        algo = build_ppo_config([Replica(e) for e in exps]).build_algo()
        try:
            sample, update, steps, _ = iteration_flops(algo)
        finally:
            algo.stop()
        cache[key] = (sample + update) / steps
    return cache[key], exps[0]


def plan_flops(game: str, seeds: int, folder: Path) -> list[dict[str, Any]]:
    """One row per experiment the full plan of `game` trains: its egos' env steps and FLOPs per env step (see the module docstring)."""
    plan = plan_for(game, seeds=seeds)
    repro = Reproduction(plan, folder / "plan", log=lambda _: None)
    stand_ins = {str(folder / "plan" / POPULATIONS_DIR / sp["name"]): sp for sp in plan.selfplay}
    rows, cache = [], {}
    for raw in repro.training():
        population = raw["population"]
        if population in stand_ins:
            population = _stand_in(game, stand_ins[population], folder)
        settings = {k: v for k, v in raw.items() if k not in ("name", "seed")}
        per_step, ego = ego_flops_per_step({**settings, "population": population}, cache)
        egos_steps = repro.train_steps(raw) * len(plan.seeds)
        rows.append(
            {
                "experiment": raw["name"],
                "partners": len(ego.train),
                "ego_env_steps": egos_steps,
                "mflop_per_step": per_step / 1e6,
                "tflop": egos_steps * per_step / 1e12,
            }
        )
    return rows


def selfplay_flops(game: str, run: Path) -> dict[str, float]:
    """The self-play stage as `run` (a `reproduce` game folder past it) trained it: its pairs' env steps x a pair's FLOPs per env step."""
    plan = plan_for(game)
    base = config_files.load(config_file(f"selfplay_{game}.yaml"), schema=SelfPlayConfig)
    cfg = config_files.checked(_merge(base, plan.selfplay[0]), SelfPlayConfig, ARGUMENTS).first.resolve()
    algo = build_selfplay_config(cfg).build_algo()
    try:
        before = algo.train()[ENV_RUNNER_RESULTS][NUM_ENV_STEPS_SAMPLED_LIFETIME]
        per_iteration = algo.train()[ENV_RUNNER_RESULTS][NUM_ENV_STEPS_SAMPLED_LIFETIME] - before
        sample, episodes = flops(algo.env_runner.sample)
        update, _ = flops(fixed_update(algo, episodes))
    finally:
        algo.stop()
    reports = sorted(run.glob(f"{POPULATIONS_DIR}/*/selfplay_report.csv"))
    steps = int(sum(pd.read_csv(r)["env_steps"].sum() for r in reports))
    per_step = (sample + update) / per_iteration
    return {
        "pairs": sum(len(pd.read_csv(r)) for r in reports),
        "env_steps": steps,
        "mflop_per_step": per_step / 1e6,
        "tflop": steps * per_step / 1e12,
    }


def adapt_flops(game: str, seeds: int, run: Path, folder: Path) -> dict[str, float]:
    """The adapt stage of the plan on `run`'s populations: every curve's env steps x its ego's FLOPs per env step.

    A curve trains its ego with the new partner as its only partner and lam 0, so each base
    method's arithmetic is counted on a one-partner stand-in population; evaluation is left out.
    """
    plan = plan_for(game, seeds=seeds)
    repro = Reproduction(plan, run, log=lambda _: None)
    experiments = {e["name"]: e for e in repro.training()}
    one = partners.from_partners("stand-in-one", game, {}, [RandomLegalPartner("sp00")], [])
    stand_in = str(one.save(folder / "stand-in-one.json"))
    curves, tflop, cache = 0, 0.0, {}
    for target, _, settings, egos_of in repro.adapt_jobs():
        names = repro.adapt_partners(target)
        raw = {k: v for k, v in experiments[egos_of].items() if k not in ("name", "seed", "population")}
        if raw.get("method") == "modular":
            raw["lam"] = 0.0
        per_step, ego = ego_flops_per_step({**raw, "population": stand_in}, cache)
        budget = {**plan.adapt_overrides, **settings}.get("steps") or envs.game(game).adapt_defaults(
            ego.exp.ppo.rollout_per_partner
        ).steps  # as `adapt.protocol` reads it
        n = len(plan.seeds) * len(names)
        curves += n
        tflop += n * budget * per_step / 1e12
    return {"curves": curves, "tflop": tflop}


def measure(
    game: str, repeats: int, folder: Path, seeds: int, run: Path | None = None
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """FLOPs per env step and achieved GFLOP/s of one iteration of `ours` for `game`, and the plan's floor (with its rows)."""
    config = ours(population_of(game, folder), SEEDS)
    algo = config.build_algo()
    try:
        sample_flops, update_flops, steps, episodes = iteration_flops(algo)
        update = fixed_update(algo, episodes)
        seconds = median_seconds({"sample": algo.env_runner.sample, "update": update}, repeats)
    finally:
        algo.stop()
    hidden = envs.game(game).training_defaults().hidden
    peak = peak_gflops(config.minibatch_size, hidden)
    peak_bf16 = peak_gflops(config.minibatch_size, hidden, dtype=torch.bfloat16)
    row = {
        "env": game,
        "env_steps_per_iteration": steps,
        "sample_mflop_per_step": sample_flops / steps / 1e6,
        "update_mflop_per_step": update_flops / steps / 1e6,
        "sample_gflops": sample_flops / seconds["sample"] / 1e9,
        "update_gflops": update_flops / seconds["update"] / 1e9,
        "peak_gflops": peak,
        "peak_bf16_gflops": peak_bf16,
        "update_at_peak": update_flops / seconds["update"] / 1e9 / peak,
    }
    plan_rows = plan_flops(game, seeds, folder)
    plan_flop = sum(r["tflop"] for r in plan_rows) * 1e12
    plan_steps = sum(r["ego_env_steps"] for r in plan_rows)
    cores = int(ray.cluster_resources().get("CPU", 1))
    row.update(
        {
            "plan_ego_steps": plan_steps,
            "plan_mflop_per_step": plan_flop / plan_steps / 1e6,
            "plan_train_floor_min": plan_flop / (cores * peak * 1e9) / 60,
            "plan_train_floor_bf16_min": plan_flop / (cores * peak_bf16 * 1e9) / 60,
            "plan_target_min": TARGET_MINUTES[game],
            "trial_steps_per_s_floor": peak * 1e9 / ((sample_flops + update_flops) / steps),
        }
    )
    if run is not None:  # the stages around training, as that run needed them; at the ego's peak (a lower bound)
        selfplay, adapt = selfplay_flops(game, run), adapt_flops(game, seeds, run, folder)
        whole = plan_flop + (selfplay["tflop"] + adapt["tflop"]) * 1e12
        row.update(
            {
                "run": str(run),
                "selfplay_env_steps": selfplay["env_steps"],
                "selfplay_mflop_per_step": selfplay["mflop_per_step"],
                "selfplay_floor_min": selfplay["tflop"] * 1e12 / (cores * peak * 1e9) / 60,
                "adapt_curves": adapt["curves"],
                "adapt_floor_min": adapt["tflop"] * 1e12 / (cores * peak * 1e9) / 60,
                "plan_floor_min": whole / (cores * peak * 1e9) / 60,
                "plan_floor_bf16_min": whole / (cores * peak_bf16 * 1e9) / 60,
            }
        )
    return row, plan_rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="timed calls of each of sampling and the update")
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks", "hanabi"], choices=["bandit", "blocks", "hanabi"])
    parser.add_argument("--seeds", type=int, default=3, help="seeds of the plans whose floor is counted")
    parser.add_argument(
        "--run",
        type=Path,
        help="a `reproduce` game folder of the one game given, past its self-play stage: also count self-play as it "
        "trained there and the adapt stage on its populations (evaluation left out)",
    )
    args = parser.parse_args()
    if args.run is not None and (len(args.games) != 1 or not (args.run / POPULATIONS_DIR).is_dir()):
        parser.error(f"--run {args.run}: needs one --games and a reproduce game folder with {POPULATIONS_DIR}/")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    rows, plans = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for game in args.games:
            row, plans[game] = measure(game, args.repeats, Path(tmp), args.seeds, args.run)
            rows.append(row)
            print(pd.DataFrame(plans[game]).to_string(index=False, float_format="{:.3g}".format), flush=True)
            print(pd.DataFrame(rows).to_string(index=False, float_format="{:.3g}".format), flush=True)
    ray.shutdown()
    result = {"seeds_per_trial": SEEDS, "plan_seeds": args.seeds, "repeats": args.repeats, "rows": rows, "plans": plans}
    print(f"wrote {write_result('flop_floor' if args.run is None else f'flop_floor_{args.games[0]}_run', result)}")


if __name__ == "__main__":
    main()
