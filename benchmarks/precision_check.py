"""Does the opt-in bfloat16 learner train the same egos? One experiment's seeds in float32 and in bfloat16, compared.

    OMP_NUM_THREADS=1 python -m benchmarks.precision_check FLOAT32_GAME_DIR EXPERIMENT BFLOAT16_GAME_DIR EXPERIMENT_BF16 [--name NAME]

The float32 side is usually a reproduction's train stage (`<out>/<game>`, experiment
`<population>__<label>`), the bfloat16 side the same experiment trained again with
`ppo.precision: bfloat16` (`rllib-conv train EXP.yaml --storage <dir>/<game>/runs`, an
experiment named `<population>__<label>-bf16`). Per seed and training partner, the final
evaluation (eval.json, `eval/mean/<partner>`) and the last iteration's training return;
per metric, each side's mean over seeds with its 95% t-interval and the paired difference
bfloat16 - float32 over the seeds both hold (the seed is the unit). Same science when every
paired interval holds 0 or, failing that, the difference is smaller than what the claims
turn on. Writes `benchmarks/results/<NAME>.json` (default `precision_check`).

`--adaptation` adds the egos adapted to new partners: each side's `adaptation/<experiment>.csv`
under its game folder (the bfloat16 egos adapted with `rllib-conv adapt ... --name
<experiment>`, which adapts in their precision), per seed the mean over its new partners of
the curve's AUC, its step-0 and last return, and the gain over not adapting (AUC - step 0).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from analysis.loaders import CONFIG_PREFIX, load_adaptation, load_trial_summaries, trial_dirs
from analysis.summaries import adaptation_auc, mean_ci
from benchmarks._common import write_result
from rllib_conv.common.run_folders import experiment_of, split_experiment

SIDES = ("float32", "bfloat16")


def seed_rows(game_dir: Path, experiment: str) -> pd.DataFrame:
    """One row per seed of `experiment` under `game_dir`: its final evaluation per partner and its last training return."""
    trials = [t for t in trial_dirs(game_dir) if experiment_of(t).name == experiment]
    if not trials:
        raise SystemExit(f"no trained ego of experiment {experiment!r} under {game_dir}/runs")
    summaries = load_trial_summaries(trials)  # config, last logged iteration and eval.json, one row per seed
    evals = [c for c in summaries.columns if c.startswith("eval/mean/")]
    rows = pd.DataFrame(
        {
            "seed": summaries[CONFIG_PREFIX + "seed"].astype(int),
            "eval_mean": summaries[evals].mean(axis=1),
            **{f"eval/{c.split('/', 2)[2]}": summaries[c] for c in evals},
            "train_return_mean": summaries["return_mean"].astype(float),
        }
    )
    return rows.set_index("seed").sort_index()


def adaptation_rows(game_dir: Path, experiment: str) -> pd.DataFrame:
    """One row per seed of `experiment`'s adaptation curves under `game_dir`: means over its new partners of AUC, start, end, gain."""
    curves = load_adaptation(game_dir)
    population, label = split_experiment(experiment)
    curves = curves[(curves["population"] == population) & (curves["label"] == label)]
    if curves.empty:
        raise SystemExit(f"no adaptation curves of experiment {experiment!r} under {game_dir}/adaptation")
    auc = adaptation_auc(curves).assign(gain=lambda d: d["auc"] - d["start"])
    per_seed = auc.groupby("seed")[["auc", "start", "end", "gain"]].mean()
    per_seed.index = per_seed.index.astype(int)
    return per_seed.add_prefix("adapt_").sort_index()


def compare(sides: dict[str, pd.DataFrame]) -> list[dict]:
    """Per metric both sides hold: each side's mean [95% interval] over seeds and the paired difference bfloat16 - float32."""
    f32, bf16 = (sides[s] for s in SIDES)
    seeds = f32.index.intersection(bf16.index)
    out = []
    for metric in [c for c in f32.columns if c in bf16.columns]:
        row: dict = {"metric": metric, "seeds": [int(s) for s in seeds]}
        for side in SIDES:
            mean, lo, hi, n = mean_ci(sides[side].loc[seeds, metric])
            row[side] = {"mean": mean, "lo": lo, "hi": hi, "n": n}
        mean, lo, hi, n = mean_ci(bf16.loc[seeds, metric] - f32.loc[seeds, metric])
        row["difference"] = {"mean": mean, "lo": lo, "hi": hi, "n": n}
        row["interval_holds_0"] = bool(lo <= 0 <= hi)
        out.append(row)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("float32_dir", type=Path, help="the game folder of the float32 egos (a reproduction's <out>/<game>)")
    parser.add_argument("float32_experiment", help="their experiment, e.g. hanabi-selfplay__modular-lam0.5")
    parser.add_argument("bfloat16_dir", type=Path, help="the game folder of the bfloat16 egos (its runs/ holds them)")
    parser.add_argument("bfloat16_experiment", help="their experiment, e.g. hanabi-selfplay__modular-lam0.5-bf16")
    parser.add_argument("--adaptation", action="store_true", help="also compare the egos' adaptation curves (see above)")
    parser.add_argument("--name", default="precision_check")
    args = parser.parse_args()
    sides = {}
    for s in SIDES:
        folder, experiment = getattr(args, f"{s}_dir"), getattr(args, f"{s}_experiment")
        rows = seed_rows(folder, experiment)
        sides[s] = rows.join(adaptation_rows(folder, experiment)) if args.adaptation else rows
    rows = compare(sides)
    table = pd.DataFrame(
        [
            {
                "metric": r["metric"],
                **{f"{s} mean": r[s]["mean"] for s in SIDES},
                "bf16 - f32": r["difference"]["mean"],
                "lo": r["difference"]["lo"],
                "hi": r["difference"]["hi"],
                "holds 0": r["interval_holds_0"],
            }
            for r in rows
        ]
    )
    print(table.to_string(index=False, float_format="{:.3f}".format), flush=True)
    sources = {s: {"folder": str(getattr(args, f"{s}_dir")), "experiment": getattr(args, f"{s}_experiment")} for s in SIDES}
    per_seed = {s: sides[s].reset_index().to_dict(orient="records") for s in SIDES}
    print(f"wrote {write_result(args.name, {'sources': sources, 'rows': rows, 'per_seed': per_seed})}")


if __name__ == "__main__":
    main()
