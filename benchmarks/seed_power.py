"""How many seeds the bandit's ~0.01 effects need, from a report's committed per-seed data (the power note).

    python -m benchmarks.seed_power [DATA]   # default: benchmarks/results/reproduce_bandit_3seeds/data/bandit

Per population: the paired AUC differences ours λ=0.5 − BaselineAgg, − MAML and oracle − ours
(paired on (seed, partner), averaged per seed), their seed-level standard deviation, and the
seeds a 95% t-interval needs for a half-width below 0.01 (`summaries.seeds_for_half_width`).
Reads files only; prints the table (docs/reproduce.md#how-many-seeds-a-power-note quotes it).
"""

from __future__ import annotations

import argparse

import pandas as pd

from analysis import loaders
from analysis.summaries import adaptation_auc, seeds_for_half_width
from benchmarks._common import RESULTS

OURS = "modular-lam0.5"
PAIRS = ((OURS, "agg"), (OURS, "maml"), ("oracle", OURS))
HALF_WIDTH = 0.01


def power_table(data: str) -> pd.DataFrame:
    """One row per (population, difference): its mean, seed-level sd, seeds and the seeds needed for `HALF_WIDTH`."""
    auc = adaptation_auc(loaders.load_adaptation(data))
    rows = []
    for population, g in auc.groupby("population"):
        wide = g.pivot_table(index=["seed", "partner"], columns="label", values="auc")
        for a, b in PAIRS:
            if a in wide and b in wide:
                per_seed = (wide[a] - wide[b]).dropna().groupby(level="seed").mean()
                sd = float(per_seed.std(ddof=1))
                rows.append(
                    (population, f"{a} − {b}", float(per_seed.mean()), sd, len(per_seed), seeds_for_half_width(sd, HALF_WIDTH))
                )
    return pd.DataFrame(rows, columns=["population", "difference", "mean", "sd", "seeds", "seeds_needed"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", nargs="?", default=str(RESULTS / "reproduce_bandit_3seeds" / "data" / "bandit"))
    table = power_table(parser.parse_args().data)
    print(table.to_string(index=False, float_format=lambda x: f"{x:.4f}"))


if __name__ == "__main__":
    main()
