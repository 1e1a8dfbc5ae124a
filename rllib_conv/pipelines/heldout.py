"""Held-out evaluation: named agents, each a set of seeds, play every member of a held-out partner population.

This is how Carroll et al. (NeurIPS 2019) compare agents with people: PPO_SP (self-play) and
PPO_BC (PPO trained with a behaviour-cloned partner), each paired with the human proxy
H_proxy, cloned from other people's games. An agent here is one of

- `selfplay`: the pairs of a self-play population, each pair's ego-seat player (its counterpart);
- `trained`: the egos of a training experiment, each a single network (`RUN:ego`: agg, maml, ...);
- `members`: a population's members themselves in the ego seat (e.g. the BC proxies).

Each of an agent's seeds plays `episodes` scored episodes (`envs.make_scored`: on Overcooked
soups alone) with each held-out partner in its seat (in a game of more than two seats, with
every team of them, one per partner seat: `partner` is the team's name, `a+b`); the table has
one row per (agent, seed, partner): `agent, seed, player, partner, episodes, mean_return, stderr`. The seed is
the unit the report's intervals are over.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
import pandas as pd

from rllib_conv import envs
from rllib_conv.common.run_folders import read_trial_config, trial_folders
from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import score_episodes
from rllib_conv.partners.population import PartnerEntry, Population
from rllib_conv.pipelines.crossplay import counterpart_of
from rllib_conv.pipelines.pair import seat

HELDOUT_COLUMNS = ["agent", "seed", "player", "partner", "episodes", "mean_return", "stderr"]


@dataclass(frozen=True)
class Player:
    """One seed of an agent: its seed, a name for the table and the fixed player."""

    seed: int
    name: str
    player: Partner


@dataclass(frozen=True)
class HeldoutAgent:
    """A named agent: its players (one per seed) and the seat they were trained to leave to the partner."""

    label: str
    players: list[Player]
    partner_agent: str | None  # None: a trained ego's, checked against its population when it was trained


def selfplay_agent(label: str, population: Population) -> HeldoutAgent:
    """Each self-play pair's ego-seat player (the member's counterpart), seeded by the pair's seed."""
    players = [Player(_seed(e, i), e.name, counterpart_of(e, population)) for i, e in enumerate(population.partners)]
    return HeldoutAgent(label, players, population.partner_agent)


def members_agent(label: str, population: Population) -> HeldoutAgent:
    """A population's members themselves in the ego seat, seeded by each member's seed."""
    return HeldoutAgent(label, [Player(_seed(e, i), e.name, e.build()) for i, e in enumerate(population.partners)], None)


def _seed(entry: PartnerEntry, index: int) -> int:
    """A member's training seed, else its place in the population (scripted members have no seed)."""
    return int(entry.seed) if entry.seed is not None else index


def trained_agent(label: str, experiment: str | Path, seeds: list[int] | None = None) -> HeldoutAgent:
    """The single-network egos (`RUN:ego`) of a training experiment folder, one per trial seed (`seeds`: only those)."""
    players = []
    for trial in trial_folders(experiment):
        trial_seed = int(read_trial_config(trial).get("seed", 0))
        if seeds is None or trial_seed in seeds:
            # Named inside the experiment, not by absolute path: the table travels with the report's data.
            name = f"{Path(experiment).name}/{Path(trial).relative_to(experiment)}"
            players.append(Player(trial_seed, name, seat(f"{trial}:ego", trial_seed).player))
    if not players:
        raise ValueError(f"agent {label!r}: no trained ego of seeds {seeds} in {str(experiment)!r}")
    return HeldoutAgent(label, players, None)


def play_heldout(agents: list[HeldoutAgent], partners: Population, episodes: int, seed: int = 0) -> pd.DataFrame:
    """Every player of every agent with every member of `partners` (in its seat) for `episodes` scored episodes."""
    if episodes < 1:
        raise ValueError(f"episodes must be at least 1, got {episodes}")
    make_env = partial(envs.make_scored, partners.env, **partners.env_config)
    ego_agent = partners.ego_agent(make_env().possible_agents)
    rows = []
    for agent in agents:
        if agent.partner_agent not in (None, partners.partner_agent):
            raise ValueError(
                f"agent {agent.label!r} was trained with its partner in seat {agent.partner_agent!r}, "
                f"but {partners.name!r} plays seat {partners.partner_agent!r}"
            )
        for p in agent.players:
            # With several partner seats, every team of members (one per seat, in seat order; `a+b`).
            for name, members in partners.teams():
                scores = score_episodes(make_env, {ego_agent: p.player, **partners.seated(members)}, episodes, seed)
                stderr = float(scores.std(ddof=1) / np.sqrt(len(scores))) if len(scores) > 1 else 0.0
                rows.append([agent.label, p.seed, p.name, name, episodes, float(scores.mean()), stderr])
    return pd.DataFrame(rows, columns=HELDOUT_COLUMNS)
