"""Scripted cross-play: every population's partners against scripted egos that know each convention.

The ego seat is filled by the best response to one partner's convention (a copy of a
bandit convention, the `BlocksLeader` of a permutation, the same player for Hanabi);
matched pairs show what the rules allow, mismatched pairs what a wrong convention costs.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rllib_conv import envs, partners
from rllib_conv.partners.bandit import BanditConventionPartner
from rllib_conv.partners.base import Partner
from rllib_conv.partners.blocks import BlocksLeader
from rllib_conv.partners.population import PartnerEntry, Population

DEMO_POPULATIONS = ["bandit-s2-hand", "bandit-s2-hand-newtask", "bandit-user-study", "blocks-perm", "blocks-perm-newtask", "hanabi-scripted"]


def matching_ego(entry: PartnerEntry, population: Population) -> Partner:
    """Return a scripted ego that follows `entry`'s convention (self-play for other kinds)."""
    if entry.kind == "bandit_convention":
        return BanditConventionPartner(f"ego~{entry.name}", entry.params["arms"])
    if entry.kind == "blocks_permutation":
        return BlocksLeader(f"ego~{entry.name}", entry.params["perm"], population.env_config.get("new_task", False))
    return entry.build()


def scripted_crossplay(population: Population, num_episodes: int = 100, seed: int = 0) -> pd.DataFrame:
    """Return one row per (ego convention, partner) with the mean score over `num_episodes`."""
    env = envs.make(population.env, **population.env_config)
    ego_agent = next(a for a in env.possible_agents if a != population.partner_agent)
    rows = []
    for ego_entry in population.partners:
        for entry in population.partners:
            seats = {ego_agent: matching_ego(ego_entry, population), population.partner_agent: entry.build()}
            scores = partners.play_episodes(env, seats, num_episodes, seed)
            rows.append({"ego": ego_entry.name, "partner": entry.name, "matched": ego_entry.name == entry.name, "score": scores.mean()})
    return pd.DataFrame(rows)


def demo_table(names: list[str] = DEMO_POPULATIONS, num_episodes: int = 100, seed: int = 0) -> pd.DataFrame:
    """Summarise `scripted_crossplay` per population: matched vs mismatched mean score."""
    rows = []
    for name in names:
        pop = partners.get(name)
        cross = scripted_crossplay(pop, num_episodes, seed)
        mismatched = cross.loc[~cross["matched"], "score"]
        rows.append(
            {
                "population": name,
                "env": f"{pop.env} {pop.env_config}",
                "partners": len(pop.partners),
                "matched": cross.loc[cross["matched"], "score"].mean(),
                "mismatched": mismatched.mean() if len(mismatched) else np.nan,
            }
        )
    return pd.DataFrame(rows)
