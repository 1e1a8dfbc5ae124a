"""Cross-play: every member of population A (ego seat) with every member of population B (partner seat).

A member's ego-seat player is its `counterpart` (the other seat of its self-play pair);
scripted populations without one use the convention's best response (a copy of a bandit
convention, the matching `BlocksLeader`) or, for symmetric games, the partner itself.
With A = B the diagonal is self-play and the rest shows what mismatched conventions cost.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display on servers and CI
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from rllib_conv import envs  # noqa: E402
from rllib_conv.partners.bandit import BanditConventionPartner  # noqa: E402
from rllib_conv.partners.base import Partner  # noqa: E402
from rllib_conv.partners.blocks import BlocksLeader  # noqa: E402
from rllib_conv.partners.episodes import score_episodes  # noqa: E402
from rllib_conv.partners.kinds import partner_from_spec  # noqa: E402
from rllib_conv.partners.population import PartnerEntry, Population  # noqa: E402


def counterpart_of(entry: PartnerEntry, population: Population) -> Partner:
    """The ego-seat player that goes with `entry` (see the module docstring)."""
    if entry.counterpart:
        return partner_from_spec(entry.counterpart)
    if entry.kind == "bandit_convention":
        return BanditConventionPartner(f"{entry.name}-counterpart", entry.params["arms"])
    if entry.kind == "blocks_permutation":
        return BlocksLeader(f"{entry.name}-counterpart", entry.params["perm"], population.env_config.get("new_task", False))
    return entry.build()


def crossplay(a: Population, b: Population, episodes: int = 100, seed: int = 0) -> pd.DataFrame:
    """Return the mean score matrix: rows = A's members in the ego seat, columns = B's members as partners."""
    if (a.env, a.env_config, a.partner_agent) != (b.env, b.env_config, b.partner_agent):
        raise ValueError(
            f"populations {a.name!r} and {b.name!r} are for different games or seats: "
            f"{a.env} {a.env_config} seat {a.partner_agent} vs {b.env} {b.env_config} seat {b.partner_agent}"
        )
    make_env = partial(envs.make_scored, a.env, **a.env_config)
    seats = a.partner_agents
    ego_agent = a.ego_agent(make_env().possible_agents)
    # In a game of more than two seats a column's member sits in every partner seat (one player each), so the
    # diagonal is still each member's self-play.
    partners_b = [(e.name, {seat: e.build() for seat in seats}) for e in b.partners]
    rows = {}
    for entry in a.partners:
        ego = counterpart_of(entry, a)
        rows[entry.name] = {
            name: float(score_episodes(make_env, {ego_agent: ego, **seated}, episodes, seed).mean())
            for name, seated in partners_b
        }
    matrix = pd.DataFrame.from_dict(rows, orient="index")
    matrix.index.name = f"{a.name} ({ego_agent})"
    matrix.columns.name = f"{b.name} ({', '.join(seats)})"
    return matrix


def crossplay_gap(matrix: pd.DataFrame) -> dict[str, float] | None:
    """The cross-play gap of a population against itself: mean self-play (diagonal) minus mean cross-play (off-diagonal).

    What a population's conventions cost a player who meets a member it did not train
    with (the zero-shot coordination literature's "cross-play gap"). None unless the matrix
    is one population against itself (the same members in the same order, at least two).
    """
    if list(matrix.index) != list(matrix.columns) or len(matrix) < 2:
        return None
    values = matrix.to_numpy(dtype=float)
    diagonal = values.diagonal()
    off = values[~np.eye(len(values), dtype=bool)]
    return {"selfplay": float(diagonal.mean()), "crossplay": float(off.mean()), "gap": float(diagonal.mean() - off.mean())}


def write_crossplay(matrix: pd.DataFrame, out: str | Path, stem: str) -> tuple[Path, Path]:
    """Write the matrix as `<stem>.csv` and a heatmap `<stem>.png` under `out`; return both paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    csv, png = out / f"{stem}.csv", out / f"{stem}.png"
    matrix.to_csv(csv)
    n_rows, n_cols = matrix.shape
    fig, ax = plt.subplots(figsize=(max(4.0, 0.45 * n_cols + 2.5), max(3.5, 0.4 * n_rows + 2.0)))
    image = ax.imshow(matrix.to_numpy(), cmap="viridis", aspect="auto")
    ax.set_xticks(range(n_cols), matrix.columns, rotation=90, fontsize=7)
    ax.set_yticks(range(n_rows), matrix.index, fontsize=7)
    ax.set_xlabel(matrix.columns.name or "partner")
    ax.set_ylabel(matrix.index.name or "ego")
    if n_rows * n_cols <= 400:
        values = matrix.to_numpy()
        mid = (values.min() + values.max()) / 2
        for i in range(n_rows):
            for j in range(n_cols):
                colour = "black" if values[i, j] > mid else "white"  # readable on viridis' light and dark ends
                ax.text(j, i, f"{values[i, j]:.2g}", ha="center", va="center", fontsize=6, color=colour)
    fig.colorbar(image, ax=ax, label="mean score")
    ax.set_title("cross-play (diagonal: self-play)" if list(matrix.index) == list(matrix.columns) else "cross-play")
    fig.tight_layout()
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return csv, png
