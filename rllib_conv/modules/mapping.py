"""Agent -> module mapping: every episode is played with one partner, partners in turn.

In a `ReplicatedGame` the agents carry their replica (`player_0#2`) and map to that
replica's modules (`ego@p#2`, `partner@p#2`); every replica counts episodes the same way,
so each pairs its episodes with its partners exactly as it would alone.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

from rllib_conv.modules.multi import AGG_HEAD_ID, REPLICA_SEPARATOR, ego_id, partner_id, replica_id

_CACHE = 4096


class PartnerMapping:
    """Policy-mapping function pairing each episode with one partner, round robin.

    The ego agent maps to its head for that partner (or to the single `ego` head when
    `shared_head`, i.e. BaselineAgg) and the partner agent to the partner's module.
    Episodes are assigned in the order an env runner first sees them, so episodes are
    spread evenly over partners and the assignment is reproducible.
    """

    def __init__(
        self, partners: list[str], ego_agent: str, partner_agent: str, shared_head: bool = False, replica_partners: list[list[str]] | None = None
    ) -> None:
        if not partners or (replica_partners is not None and not all(replica_partners)):
            raise ValueError("PartnerMapping needs at least one partner")
        self.partners = list(partners)
        # Replica r's partners (default: `partners` for every replica).
        self.replica_partners = [list(p) for p in replica_partners] if replica_partners is not None else None
        self.ego_agent = ego_agent
        self.partner_agent = partner_agent
        self.shared_head = shared_head
        self._next = 0
        self._assigned: OrderedDict[str, int] = OrderedDict()
        self._focus: int | None = None

    def focus(self, partner: str | None) -> None:
        """Pair every new episode with `partner` only (None: back to round robin). Used by MAML."""
        self._focus = None if partner is None else self.partners.index(partner)

    def get_state(self) -> dict[str, Any]:
        """The round-robin position and current assignments (saved with checkpoints)."""
        return {"next": self._next, "assigned": list(self._assigned.items()), "focus": self._focus}

    def set_state(self, state: dict[str, Any]) -> None:
        """Restore a state from `get_state`."""
        self._next, self._focus = state["next"], state["focus"]
        self._assigned = OrderedDict(state["assigned"])

    def partner_for(self, episode_id: str) -> str:
        """Return the partner assigned to `episode_id`, assigning the next one on first sight."""
        return self.partners[self._index_for(episode_id)]

    def _index_for(self, episode_id: str) -> int:
        """The index (into `partners`) assigned to `episode_id`, assigning the next one on first sight."""
        if episode_id not in self._assigned:
            if self._focus is not None:
                self._assigned[episode_id] = self._focus
            else:
                self._assigned[episode_id] = self._next % len(self.partners)
                self._next += 1
            if len(self._assigned) > _CACHE:
                self._assigned.popitem(last=False)
        return self._assigned[episode_id]

    def __call__(self, agent_id: str, episode: Any, **kwargs: Any) -> str:
        agent, sep, tag = agent_id.rpartition(REPLICA_SEPARATOR)
        replica = int(tag) if sep and tag.isdigit() else None
        agent = agent if replica is not None else agent_id
        index = self._index_for(episode.id_)
        own = self.replica_partners[replica] if replica is not None and self.replica_partners is not None else self.partners
        name = own[index % len(own)]
        if agent == self.ego_agent:
            return replica_id(AGG_HEAD_ID if self.shared_head else ego_id(name), replica)
        if agent == self.partner_agent:
            return replica_id(partner_id(name), replica)
        raise ValueError(f"agent {agent_id!r} is neither the ego ({self.ego_agent!r}) nor the partner ({self.partner_agent!r})")
