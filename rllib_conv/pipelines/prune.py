"""`rllib-conv partners prune`: a self-play population cut to its most diverse training pairs (HSP's pool pruning).

Every training pair with a counterpart is profiled (`partners.event_profiles.event_profile`:
events per episode of the partner's seat beside its counterpart), and `keep` of them are chosen
by farthest-point selection on those profiles (`most_diverse`). The new population holds the
chosen pairs (with their FCP snapshots, `<pair>-init`/`-mid`, where the source has them) and every
test member unchanged; their networks are copied in, so the folder stands alone like any
population. `prune_report.csv` lists every training pair's profile and whether it was kept.
Assembled in a temporary folder and moved into place whole (`folder_replaced_atomically`).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd

from rllib_conv.common.atomic_files import folder_replaced_atomically
from rllib_conv.common.run_folders import POPULATION_FILE
from rllib_conv.partners.event_profiles import event_profile, most_diverse, profiled_events
from rllib_conv.partners.population import PartnerEntry, Population

PRUNE_REPORT_FILE = "prune_report.csv"
SNAPSHOT_TAGS = ("-init", "-mid")  # FCP's snapshots of a pair, named after it (`pipelines.selfplay.fcp_members`)


def pair_of(entry: PartnerEntry, pairs: set[str]) -> str | None:
    """The training pair `entry` belongs to: its own name, or the pair an FCP snapshot of it was taken from."""
    if entry.name in pairs:
        return entry.name
    for tag in SNAPSHOT_TAGS:
        if entry.name.endswith(tag) and entry.name[: -len(tag)] in pairs:
            return entry.name[: -len(tag)]
    return None


def pruned_name(population: Population, keep: int) -> str:
    """The default name of `population` pruned to `keep` training pairs."""
    return f"{population.name}-pruned{keep}"


def prune(
    pop: Population, keep: int, episodes: int = 10, seed: int = 0, name: str | None = None
) -> tuple[Population, pd.DataFrame]:
    """`pop` with only its `keep` most diverse training pairs (see the module docstring), not yet written, and the report
    of every training pair. ValueError when there is nothing to choose from."""
    profiled_events(pop)
    if len(pop.partner_agents) != 1:
        raise ValueError(f"population {pop.name!r}: pruning needs one partner seat, it has {len(pop.partner_agents)}")
    paired = [e for e in pop.entries("train") if e.counterpart is not None]
    if not 1 <= keep < len(paired):
        raise ValueError(
            f"--keep must be between 1 and {len(paired) - 1} (population {pop.name!r} has {len(paired)} training pairs "
            f"with counterparts), got {keep}"
        )
    rows = pd.DataFrame([{"partner": e.name, **event_profile(pop, e, episodes, seed)} for e in paired])
    events = [c for c in rows.columns if c not in ("partner", "score")]
    rank = {row: n for n, row in enumerate(most_diverse(rows[events].to_numpy(), keep))}
    rows["order"] = pd.array([rank.get(row) for row in range(len(rows))], dtype="Int64")  # the order chosen in
    rows["kept"] = rows["order"].notna()
    kept = set(rows.loc[rows["kept"], "partner"])
    pairs = {e.name for e in paired}
    entries = [
        e
        for e in pop.partners
        if e.split == "test" or pair_of(e, pairs) in kept or (e.split == "train" and pair_of(e, pairs) is None)
    ]
    pruned = Population(
        name=name or pruned_name(pop, keep),
        env=pop.env,
        env_config=pop.env_config,
        partner_agent=pop.partner_agent,
        description=f"{pop.description}; pruned to its {keep} most diverse training pairs of {len(paired)} by their event profiles",
        partners=[e.model_copy(deep=True) for e in entries],
    )
    return pruned, rows


def write_pruned(population: Population, report: pd.DataFrame, folder: Path) -> Path:
    """Write `population` into `folder` (its networks copied in, paths relative) with `report`, replacing what was there
    (callers refuse an existing one first: `population.refuse_existing`); the folder whole or not at all."""
    with folder_replaced_atomically(folder) as staging:
        for entry in population.partners:
            _copy_networks(entry, staging)
        population.save(staging / POPULATION_FILE)
        report.to_csv(staging / PRUNE_REPORT_FILE, index=False)
    return folder


def _copy_networks(entry: PartnerEntry, staging: Path) -> None:
    """Copy `entry`'s checkpoint (and its counterpart's) into `staging`, pointing the entry at the copies (relative)."""
    if entry.checkpoint:
        relative = f"partners/{entry.name}"
        shutil.copytree(entry.checkpoint, staging / relative)
        entry.checkpoint = relative
        if "checkpoint" in entry.params:
            entry.params["checkpoint"] = relative
    if entry.counterpart and "checkpoint" in entry.counterpart.get("params", {}):
        relative = f"counterparts/{entry.name}"
        shutil.copytree(entry.counterpart["params"]["checkpoint"], staging / relative)
        entry.counterpart["params"]["checkpoint"] = relative
