"""HSP's biased partners on Overcooked: what each partner does beside its counterpart, against plain self-play's.

Each population folder named (an HSP one, `rllib-conv partners train tune_configs/selfplay_overcooked_hsp.yaml`,
and a control trained the same way without `hidden_utility`) plays every partner with its own counterpart for
`--episodes` episodes, both sampling as the partners act, and counts the partner seat's kitchen events per episode
(the env's `infos[seat]["events"]`) and the soups delivered. Prints a table and writes
`benchmarks/results/<--name>.json`: per partner its weights (HSP), soups and events per episode; per population the
mean pairwise L1 distance between its partners' event profiles (how different its members behave; HSP prunes its
pool by such counts) with its spread over pairs.

    OMP_NUM_THREADS=1 .venv/bin/python -m benchmarks.hsp_population populations/overcooked-hsp populations/overcooked-sp
"""

from __future__ import annotations

import argparse
import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks._common import write_result
from rllib_conv import partners
from rllib_conv.partners.event_profiles import event_profile
from rllib_conv.partners.population import PartnerEntry, Population


def play(population: Population, entry: PartnerEntry, episodes: int, seed: int) -> dict[str, Any]:
    """`entry` in its seat with its counterpart in the other: soups and the partner seat's events per episode."""
    profile = event_profile(population, entry, episodes, seed)
    score = profile.pop("score")
    return {
        "partner": entry.name,
        "weights": entry.hidden_utility,
        "score": score,
        **{f"events/{e}": n for e, n in profile.items()},
    }


def diversity(rows: pd.DataFrame) -> dict[str, float]:
    """Mean and spread of the pairwise L1 distance between the partners' event profiles (events per episode)."""
    profiles = rows.filter(like="events/").to_numpy()
    distances = [float(np.abs(a - b).sum()) for a, b in itertools.combinations(profiles, 2)]
    if not distances:
        return {"pairs": 0}
    return {"pairs": len(distances), "mean_l1": float(np.mean(distances)), "min_l1": min(distances), "max_l1": max(distances)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("populations", nargs="+", help="population folders (HSP, then its control)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per partner (default 10)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--name", default="hsp_population", help="the result file's name (default hsp_population)")
    args = parser.parse_args()
    out: dict[str, Any] = {"episodes": args.episodes, "populations": {}}
    for folder in args.populations:
        population = partners.get(folder)
        paired = [e for e in population.entries() if e.counterpart is not None]  # FCP's snapshots have none
        if not paired:
            raise SystemExit(f"hsp_population: {folder!r} has no partner with a counterpart: not a self-play population")
        rows = pd.DataFrame([play(population, e, args.episodes, args.seed) for e in paired])
        events = [c for c in rows.columns if c.startswith("events/") and rows[c].any()]
        print(f"\n{population.name} ({Path(folder)}): {population.description}")
        print(rows[["partner", "score", *events]].round(1).to_string(index=False))
        spread = diversity(rows)
        print("pairwise L1 between event profiles:", {k: round(v, 1) for k, v in spread.items()})
        out["populations"][population.name] = {
            "folder": str(folder),
            "description": population.description,
            "partners": rows.to_dict(orient="records"),
            "diversity": spread,
        }
    print("wrote", write_result(args.name, out))


if __name__ == "__main__":
    main()
