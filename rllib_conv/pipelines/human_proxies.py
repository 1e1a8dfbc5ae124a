"""`rllib-conv human-proxies overcooked`: Carroll et al.'s BC and H_proxy partners, trained from the 2019 human data.

Per layout and seed, behaviour cloning (`training.behaviour_cloning`) on upstream's train
split gives `BC` and on its test split (other people) gives `H_proxy`. Both are saved into
the cache folder, never the repository (the data may not be redistributed):
`<cache>/proxies/<layout>/{bc,hproxy}/seed<s>/` with a population manifest beside them, so
the built-in populations `overcooked-<layout>-bc` and `-hproxy` (`partners.overcooked`)
resolve to them and `pair`, `crossplay`, `adapt` and the play server load them as any other.

The table (one row per layout and seed, also written to `<cache>/proxies/human_proxies.csv`):
action-prediction accuracy (argmax vs the logged action) of each model on the other split and
on the trials of its own split held out from its training, over every row and over the
non-STAY rows; the sparse return (horizon 400) of BC + H_proxy and of BC + BC (two
samplers of the same BC), each seat order for half of the episodes; the logged human pairs'
return per 400 steps for comparison; and the wall time of each training.

Stay rule (`BCSettings.stay`, default `drop`, set there): about 70% of logged actions are
STAY (the game was logged faster than people act). Measured on cramped_room (seeds 0-2, 10
episodes each, sparse return; `benchmarks/results/human_proxies.json`), where the logged
human pairs score ~117 per 400 steps:

| rule | BC accuracy on test split: all rows / non-STAY rows | BC predicts STAY | BC + BC | BC + H_proxy |
|---|---|---|---|---|
| keep | 0.70 / 0.05 | 95% of rows | 49 (38-60) | 33 (24-42) |
| collapse (first STAY of a run) | 0.55 / 0.43 | 56% | 72 (64-76) | 52 (38-62) |
| drop | 0.21 / 0.71 | never | 82 (78-90) | 74 (44-104) |

Keeping every row buys accuracy by predicting STAY (the majority class) and clones a cook
who mostly stands still; dropping STAY rows predicts people's moves best and gives the pairs
closest to the people's score. A proxy should play like the people it stands for, so `drop`
is the default; it can still pause by walking into a counter, as people's key presses did.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from rllib_conv.common.atomic_files import write_text_atomically
from rllib_conv.common.run_folders import POPULATION_FILE
from rllib_conv.common.sealed import seal
from rllib_conv.common.seeds import stream_seed
from rllib_conv.envs.overcooked.env import HORIZON, OvercookedEnv
from rllib_conv.envs.overcooked.human_data import LAYOUTS, cache_folder, trajectories
from rllib_conv.partners.episodes import score_episodes
from rllib_conv.partners.overcooked import PROXIES_DIR, PROXY_KINDS, population_name, proxies_folder
from rllib_conv.partners.population import PartnerEntry, Population
from rllib_conv.partners.trained import TrainedPolicyPartner
from rllib_conv.training import behaviour_cloning as bc

REPORT_FILE = "human_proxies.csv"


def member_name(seed: int) -> str:
    """A proxy population member's name (and checkpoint folder): `seed<s>`."""
    return f"seed{seed}"


def _check(layouts: Sequence[str], seeds: Sequence[int], episodes: int) -> None:
    if not layouts:
        raise ValueError("layouts: give at least one layout")
    unknown = [layout for layout in layouts if layout not in LAYOUTS]
    if unknown:
        raise ValueError(f"layouts: {unknown} have no human data; choose from {', '.join(LAYOUTS)}")
    if not seeds or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds):
        raise ValueError(f"seeds must be a non-empty list of integers >= 0, got {list(seeds)!r}")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds must be distinct, got {list(seeds)!r}")
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 2 or episodes % 2:
        raise ValueError(f"episodes must be an even integer >= 2 (each seat order plays half), got {episodes!r}")


def report_path(cache: str | os.PathLike[str] | None = None) -> Path:
    """Where `run` writes its whole table (every accuracy, time and return): `<cache>/proxies/human_proxies.csv`."""
    return cache_folder(cache) / PROXIES_DIR / REPORT_FILE


def human_return(frame: pd.DataFrame, horizon: int = HORIZON) -> float:
    """The logged human pairs' sparse return per `horizon` steps (their soups at the game's 20 points each)."""
    seat0 = frame[frame["seat"] == 0]
    return float(seat0["reward"].sum() / len(seat0) * horizon) if len(seat0) else float("nan")


def pair_return(layout: str, first: str, second: str, episodes: int, seed: int) -> float:
    """Mean sparse return of two proxy checkpoints (sampling), `first` in seat 0 for half the episodes, then swapped."""
    half = episodes // 2
    scores = []
    for order, (a, b) in enumerate(((first, second), (second, first))):
        players = {
            "player_0": TrainedPolicyPartner("a", a, greedy=False, seed=seed),
            "player_1": TrainedPolicyPartner("b", b, greedy=False, seed=seed + 1),
        }
        scores.append(
            score_episodes(lambda: OvercookedEnv(layout, shaping=0.0), players, half, seed=stream_seed(seed, f"pair{order}"))
        )
    return float(np.concatenate(scores).mean())


def _write_population(layout: str, kind: str, seeds: Sequence[int], cache: str | os.PathLike[str] | None) -> Population:
    folder = proxies_folder(layout, kind, cache)
    split = PROXY_KINDS[kind]
    entries = [
        PartnerEntry(
            name=member_name(s),
            kind="trained_policy",
            # Sampling, as Carroll et al.'s proxies act; the checkpoint is relative to the manifest's folder.
            params={"checkpoint": member_name(s), "greedy": False, "seed": s},
            split="train" if kind == "bc" else "test",
            checkpoint=member_name(s),
            seed=s,
        )
        for s in seeds
    ]
    population = Population(
        name=population_name(layout, kind),
        env="overcooked",
        env_config={"layout": layout},
        description=f"behaviour cloning of the 2019 human {split} trials on {layout} (trained locally; do not redistribute)",
        partners=entries,
    )
    population.save(folder / POPULATION_FILE)
    return population


def run(
    layouts: Sequence[str],
    seeds: Sequence[int] = (0, 1, 2),
    cache: str | os.PathLike[str] | None = None,
    settings: bc.BCSettings | None = None,
    episodes: int = 10,
    progress: bool = False,
) -> pd.DataFrame:
    """Train BC (train split) and H_proxy (test split) per layout and seed into the cache; return the table (module docstring)."""
    _check(layouts, seeds, episodes)
    settings = settings or bc.BCSettings()
    rows = []
    for layout in layouts:
        frames = {split: trajectories(layout, split, cache) for split in ("train", "test")}
        steps = {split: bc.encode_trajectories(frame, layout) for split, frame in frames.items()}
        for seed in seeds:
            row: dict = {"layout": layout, "seed": seed, "stay": settings.stay}
            paths = {}
            for kind, split in PROXY_KINDS.items():
                other = "test" if split == "train" else "train"
                result = bc.train(steps[split], settings, seed=seed)
                path = proxies_folder(layout, kind, cache) / member_name(seed)
                if path.exists():  # a rerun replaces the checkpoint whole: no file of the old one survives
                    shutil.rmtree(path)
                bc.save(result, path)
                seal(path)
                paths[kind] = str(path)
                held = steps[split].take(np.isin(steps[split].trial, result.holdout_trials))
                for name, part in ((f"{other}_split", steps[other]), ("own_heldout", held)):
                    if len(part):
                        for key, value in bc.accuracy(result.module, part).items():
                            if key != "rows":
                                row[f"{kind}_{key}_{name}"] = value
                row[f"{kind}_seconds"] = round(result.seconds, 2)
                row[f"{kind}_epochs"] = result.best_epoch
            row["return_bc_hproxy"] = pair_return(layout, paths["bc"], paths["hproxy"], episodes, seed)
            row["return_bc_bc"] = pair_return(layout, paths["bc"], paths["bc"], episodes, seed)
            row["human_return_train"] = human_return(frames["train"])
            row["human_return_test"] = human_return(frames["test"])
            rows.append(row)
            if progress:
                print(
                    f"[{layout}] seed {seed}: BC {row['bc_seconds']} s, H_proxy {row['hproxy_seconds']} s; "
                    f"BC+H_proxy {row['return_bc_hproxy']:.0f}, BC+BC {row['return_bc_bc']:.0f} "
                    f"(people {row['human_return_test']:.0f} per {HORIZON} steps)",
                    flush=True,
                )
        for kind in PROXY_KINDS:
            _write_population(layout, kind, seeds, cache)
    table = pd.DataFrame(rows)
    report = report_path(cache)
    report.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomically(report, table.to_csv(index=False))
    return table
