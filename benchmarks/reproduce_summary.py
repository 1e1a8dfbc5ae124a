"""The paper's headline numbers from a `rllib-conv reproduce` folder, with seed-level 95% intervals, as one table and JSON.

Reads only files (through `analysis.loaders`): per population and method the env steps
its egos trained for; the adaptation AUC (mean return over the evaluation points, per
(seed, test partner) curve), on the bandit beside the uniform-prior adapter's AUC at the
same points (`analysis.summaries.uniform_prior_return`); the zero-shot return; the
marginal distance; each held-out agent's score (Overcooked's human proxies). Intervals are
the report's: each seed's mean over its test partners, then a t-interval over seeds
(`analysis.summaries.seed_summary`; n = seeds).
Writes `benchmarks/results/reproduce_<name>.json` with the reproduce command recorded in
the folder's plan.json.

    .venv/bin/python -m benchmarks.reproduce_summary ROOT/bandit --name bandit
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pandas as pd

from analysis import loaders
from analysis.summaries import adaptation_auc, seed_summary, uniform_prior_return
from benchmarks._common import write_result

BANDIT_CONTEXTS = 4
BY = ["population", "label"]


def _cis(df: pd.DataFrame, value: str) -> dict[tuple[str, str], dict]:
    """Per (population, label): the seed-level mean, 95% interval and seed count of `value`."""
    table = seed_summary(df, BY, value)
    return {(r.population, r.label): {"mean": r.mean, "lo": r.lo, "hi": r.hi, "n": int(r.n)} for r in table.itertuples()}


def _uniform_prior_auc(population: str, steps: list[int]) -> float | None:
    match = re.match(r"bandit-s(\d)-", population)
    if not match or not steps:
        return None
    return sum(uniform_prior_return(BANDIT_CONTEXTS, int(match.group(1)), t) for t in steps) / len(steps)


def summary(root: Path) -> dict:
    """Env steps each ego trained for, adaptation AUC (with the gap to the uniform-prior adapter), zero-shot, marginals and held-out scores per population and method."""
    out: dict = {"training": [], "adaptation": [], "zeroshot": [], "marginals": [], "heldout": []}
    training = loaders.load_training(root)
    if not training.empty:
        last = training.groupby(["population", "label", "run"])["steps"].max()
        for (population, label), steps in last.groupby(["population", "label"]):
            out["training"].append(
                {"population": population, "method": label, "env_steps": sorted(int(s) for s in steps.unique())}
            )
    curves = loaders.load_adaptation(root)
    if not curves.empty:
        aucs = adaptation_auc(curves)
        cis = {key: _cis(aucs, key) for key in ("auc", "start", "end")}
        for population, label in sorted(cis["auc"]):
            row = {"population": population, "method": label, **{key: cis[key][(population, label)] for key in cis}}
            steps = sorted(
                curves.loc[(curves["population"] == population) & (curves["label"] == label), "steps"].unique().tolist()
            )
            reference = _uniform_prior_auc(population, steps)
            if reference is not None:
                row["uniform_prior_auc"] = reference
                row["gap_to_uniform_prior"] = reference - row["auc"]["mean"]
            out["adaptation"].append(row)
    zeroshot = loaders.load_zeroshot(root)
    if not zeroshot.empty:
        value = "exact_return" if zeroshot["exact_return"].notna().all() else "mean_return"
        for (population, label), ci in _cis(zeroshot, value).items():
            out["zeroshot"].append({"population": population, "method": label, "return": ci})
    marginals = loaders.load_marginals(root)
    if not marginals.empty:
        # By label, not (method, lam): low-dimensional z at lam 0.5 is a different ego from modular at lam 0.5.
        for (population, label), ci in _cis(marginals, "distance").items():
            out["marginals"].append({"population": population, "method": label, "distance": ci})
    heldout = loaders.load_heldout(root)
    if not heldout.empty:
        # Each agent's seeds against every held-out member: per seed the mean over the members, then over seeds.
        partners = loaders.read_plan(root).get("heldout", {}).get("partners", "")
        for (_, agent), ci in _cis(heldout.rename(columns={"agent": "label"}).assign(population=partners), "mean_return").items():
            out["heldout"].append({"population": partners, "method": agent, "score": ci})
    return out


def _fmt(ci: dict) -> str:
    return f"{ci['mean']:.3f} [{ci['lo']:.3f}, {ci['hi']:.3f}] n={ci['n']}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("root", type=Path, help="a reproduce game folder (e.g. reproduce/bandit)")
    parser.add_argument("--name", required=True, help="results file name: benchmarks/results/reproduce_<name>.json")
    args = parser.parse_args()
    if not args.root.is_dir():
        parser.error(f"root {str(args.root)!r} is not a folder")
    data = summary(args.root)
    for section, rows in data.items():
        print(f"\n{section}")
        for row in rows:
            cells = [
                f"{k} {_fmt(v)}" if isinstance(v, dict) else f"{k} {v:.3f}" if isinstance(v, float) else f"{k} {v}"
                for k, v in row.items()
            ]
            print("  " + " | ".join(cells))
    stages = loaders.load_stage_times(args.root).to_dict(orient="records")
    plan = loaders.read_plan(args.root)
    path = write_result(f"reproduce_{args.name}", {"root": str(args.root), "plan": plan, "stages": stages, **data})
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
