"""Agent -> module mapping: every episode is played with one partner per partner seat, chosen by a `partner_schedule`.

A two-seat game has one partner seat. In a game of k seats, one ego and k-1 partner seats,
each episode draws a partner for every partner seat (the same partner may sit in several):
each partner agent maps to its partner's module and the ego to its head for that team of
partners in seat order (`ego@a+b`, `partners.population.team_name`), or to the single head when shared.

In a `ReplicatedGame` the agents carry their replica (`player_0#2`) and map to that
replica's modules (`ego@p#2`, `partner@p#2`); every replica counts episodes the same way
and draws from its own generator, so each pairs its episodes with its partners exactly as
it would alone.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

from rllib_conv.modules.multi import AGG_HEAD_ID, REPLICA_SEPARATOR, ego_id, partner_id, replica_id
from rllib_conv.modules.partner_schedule import RoundRobin
from rllib_conv.partners.population import team_name

_CACHE = 4096


class PartnerMapping:
    """Policy-mapping function pairing each episode with one partner per partner seat (`schedule`; default round robin).

    The ego agent maps to its head for that partner (or team of partners, one per seat in
    `partner_agent` order), or to the single `ego` head when `shared_head` (BaselineAgg); each
    partner agent maps to its partner's module. `partner_agent` is one agent, or a list of the
    k-1 partner seats of a k-seat game. Episodes are numbered in the order an env runner first
    sees them, so the assignment is reproducible (round robin spreads them evenly over
    partners, and over every team of them where there are several seats).
    """

    def __init__(
        self,
        partners: list[str],
        ego_agent: str,
        partner_agent: str | list[str],
        shared_head: bool = False,
        replica_partners: list[list[str]] | None = None,
        schedule: Any = None,
    ) -> None:
        if not partners or (replica_partners is not None and not all(replica_partners)):
            raise ValueError("PartnerMapping needs at least one partner")
        seats = [partner_agent] if isinstance(partner_agent, str) else list(partner_agent)
        if not seats or len(set(seats)) != len(seats) or ego_agent in seats:
            raise ValueError(
                f"PartnerMapping needs one or more distinct partner agents besides the ego {ego_agent!r}, got {partner_agent!r}"
            )
        self.partners = list(partners)
        # Replica r's partners (default: `partners` for every replica).
        self.replica_partners = [list(p) for p in replica_partners] if replica_partners is not None else None
        self.ego_agent = ego_agent
        self.partner_agent = partner_agent
        self.partner_agents = seats
        self.shared_head = shared_head
        self.schedule = schedule or RoundRobin()
        self._next = 0
        # Episode ID -> per replica, the partner index of each partner seat.
        self._assigned: OrderedDict[str, tuple[tuple[int, ...], ...]] = OrderedDict()
        self._focus: int | None = None

    def focus(self, partner: str | None) -> None:
        """Pair every new episode with `partner` only, in every partner seat (None: back to round robin). Used by MAML."""
        self._focus = None if partner is None else self.partners.index(partner)

    def get_state(self) -> dict[str, Any]:
        """The episode count, current assignments and the schedule's generators (saved with checkpoints)."""
        return {
            "next": self._next,
            "assigned": [[k, [list(seats) for seats in v]] for k, v in self._assigned.items()],
            "focus": self._focus,
            "schedule": self.schedule.get_state(),
        }

    def set_state(self, state: dict[str, Any]) -> None:
        """Restore a state from `get_state`."""
        self._next, self._focus = state["next"], state["focus"]
        self._assigned = OrderedDict((k, _per_replica(v)) for k, v in state["assigned"])
        self.schedule.set_state(state.get("schedule", {}))

    def _own(self, replica: int | None) -> list[str]:
        return self.replica_partners[replica] if replica is not None and self.replica_partners is not None else self.partners

    def _indices_for(self, episode_id: str) -> tuple[tuple[int, ...], ...]:
        """Every replica's partner index per partner seat for `episode_id` (one replica without replicas), drawn on first sight."""
        if episode_id not in self._assigned:
            replicas = len(self.replica_partners) if self.replica_partners is not None else 1
            seats = range(len(self.partner_agents))
            if self._focus is not None:
                self._assigned[episode_id] = ((self._focus,) * len(seats),) * replicas
            else:
                # One seat asks the schedule as it always has (`seat` only where there are several).
                self._assigned[episode_id] = tuple(
                    tuple(
                        self.schedule.index(
                            r, self._next, self._own(r if self.replica_partners else None), **({"seat": j} if j else {})
                        )
                        for j in seats
                    )
                    for r in range(replicas)
                )
                self._next += 1
            if len(self._assigned) > _CACHE:
                self._assigned.popitem(last=False)
        return self._assigned[episode_id]

    def __call__(self, agent_id: str, episode: Any, **kwargs: Any) -> str:
        agent, sep, tag = agent_id.rpartition(REPLICA_SEPARATOR)
        replica = int(tag) if sep and tag.isdigit() else None
        agent = agent if replica is not None else agent_id
        own = self._own(replica)
        names = [own[i] for i in self._indices_for(episode.id_)[replica or 0]]
        if agent == self.ego_agent:
            return replica_id(AGG_HEAD_ID if self.shared_head else ego_id(team_name(names)), replica)
        if agent in self.partner_agents:
            return replica_id(partner_id(names[self.partner_agents.index(agent)]), replica)
        raise ValueError(
            f"agent {agent_id!r} is neither the ego ({self.ego_agent!r}) nor a partner ({', '.join(map(repr, self.partner_agents))})"
        )


def _per_replica(saved: Any) -> tuple[tuple[int, ...], ...]:
    """A saved assignment as per replica, per seat indices (a checkpoint of one partner seat saved one int per replica)."""
    items = saved if isinstance(saved, (list, tuple)) else [saved]
    return tuple(tuple(item) if isinstance(item, (list, tuple)) else (item,) for item in items)
