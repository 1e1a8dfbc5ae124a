"""Pick the head an ego adapts from: the fresh head or one of its training partners' heads.

Not in the paper. A new partner's conventions are often ones the ego has met: self-play
partners of one game tend to share some, and a test partner may follow a training
partner's. The fresh head plays the task module's marginals, which mixes every known
convention move by move; a training partner's head commits to one. Before the first
update, every candidate plays the new partner in turn (one episode each per round, the
same episode seeds for every candidate, so they are compared on the same goals) until
the next round would overrun the step budget; the best mean return wins, ties going to
the earlier candidate (the fresh head first). These episodes are real interaction with
the new partner: the adaptation curve charges them as env steps.

The trade-off: a head that is only partly right wins the pick (it beats the marginals at
first) but is sharp, and PPO moves it away from the wrong part of its convention slowly.
It pays where new partners share whole conventions with training ones (blocks self-play
partners) and costs where they do not (blocks hand-designed partners), unless the heads
were trained with the head penalty (`head_l2`), which keeps them small enough to move
(`docs/benchmarks.md` has the numbers).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pettingzoo.utils.env import AECEnv, ParallelEnv

from rllib_conv.partners.base import Partner
from rllib_conv.partners.episodes import episode_stream


@dataclass(frozen=True)
class HeadPick:
    """The outcome of `pick_head`: the chosen candidate, env steps played, mean return per candidate."""

    chosen: str
    steps: int
    returns: dict[str, float]


def pick_head(
    make_env: Callable[[], AECEnv | ParallelEnv],
    players: dict[str, Partner],
    make_partner: Callable[[], Partner],
    ego_agent: str,
    partner_agent: str,
    budget: int,
    seed: int = 0,
) -> HeadPick:
    """Play each of `players` (candidate name -> ego player) with a fresh copy of the new partner; return the best.

    Rounds of one episode per candidate are played while a round of the longest episode
    seen so far fits in `budget` env steps; the first round is always played.
    """
    if not players:
        raise ValueError("pick_head needs at least one candidate head")
    streams = {
        name: episode_stream(make_env(), {ego_agent: player, partner_agent: make_partner()}, seed)
        for name, player in players.items()
    }
    scores: dict[str, list[float]] = {name: [] for name in players}
    used, longest = 0, 1
    while not scores[next(iter(players))] or used + len(players) * longest <= budget:
        for name, stream in streams.items():
            score, steps = next(stream)
            scores[name].append(score)
            used += steps
            longest = max(longest, steps)
    returns = {name: float(np.mean(s)) for name, s in scores.items()}
    return HeadPick(max(returns, key=returns.get), used, returns)
